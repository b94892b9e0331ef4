"""HTTP tests of the GUI's API: access token, CSRF header, workspace paths, numbers."""

from __future__ import annotations

import numpy as np
import pytest
from fastapi.testclient import TestClient

from tests.web.conftest import POSES_DEG, TOKEN

SMALL = {"trials": 200, "n_tests": 6}


def test_no_token_is_401_and_wrong_token_403(app):
    c = TestClient(app)
    for path in ("/", "/openapi.json", "/api/runs", "/api/session", "/static/app.js"):
        assert c.get(path).status_code == 401, path
        assert c.get(path, headers={"Authorization": "token nope"}).status_code == 403, path
    assert c.post("/api/sensitivity", json=SMALL).status_code == 401


def test_url_token_sets_cookie_and_leaves_url(app):
    c = TestClient(app)
    r = c.get(f"/?token={TOKEN}", follow_redirects=False)
    assert r.status_code == 303 and "token" not in r.headers["location"]
    cookie = r.headers["set-cookie"].lower()
    assert "httponly" in cookie and "samesite=strict" in cookie
    assert c.get("/api/runs").status_code == 200  # the cookie alone now suffices


def test_post_needs_the_csrf_header(client):
    from campaign.web.security import CSRF_HEADER

    good = client.headers.pop(CSRF_HEADER)
    assert client.post("/api/sensitivity", json=SMALL).status_code == 403
    assert client.post("/api/sensitivity", json=SMALL,
                       headers={CSRF_HEADER: "x" + good}).status_code == 403
    assert client.post("/api/sensitivity", json=SMALL,
                       headers={CSRF_HEADER: good}).status_code == 200


def test_session_gives_the_csrf_value(client):
    from campaign.web.security import csrf_value

    s = client.get("/api/session").json()
    assert s["csrf_token"] == csrf_value(TOKEN) != TOKEN


def test_sensitivity_equals_the_job(client, workspace):
    from campaign.jobs.sensitivity import ErrorSources, SensitivityOptions, run_sensitivity

    body = {**SMALL, "method": "wls", "translation_sigma_um": 30, "force_percent": 0.5,
            "seed": 3}
    got = client.post("/api/sensitivity", json=body).json()
    want = run_sensitivity(SensitivityOptions(
        n_tests=6, trials=200, method="wls", seed=3,
        errors=ErrorSources(translation_sigma=30e-6, force_relative=0.005))).to_dict()
    # same seed: the same numbers (to rounding: BLAS may sum in another order)
    for a, b in zip(got["joints"], want["joints"], strict=True):
        assert a.keys() == b.keys()
        for key in a:  # model_bias_relative is None without realism
            assert a[key] == (None if b[key] is None else pytest.approx(b[key], rel=1e-12)), key
    assert np.allclose(got["sets_Nm_per_rad"], want["sets_Nm_per_rad"], rtol=1e-12)
    assert got["noise"]["translation_sigma_um"] == pytest.approx(30)
    assert got["noise"]["force_relative_percent"] == pytest.approx(0.5)


def test_sensitivity_spread_follows_the_noise_and_the_prediction(client):
    """WLS at the true weights: the Monte-Carlo std is the planner's se within the sampling
    error; doubling the tracker sigma (tracker-dominated) about doubles both."""
    base = {"trials": 2000, "n_tests": 12, "method": "wls", "force_sigma_N": 0,
            "moment_sigma_Nm": 0, "encoder_resolution_deg": 0}
    one = client.post("/api/sensitivity", json={**base, "translation_sigma_um": 20,
                                                "rotation_sigma_urad": 50}).json()
    two = client.post("/api/sensitivity", json={**base, "translation_sigma_um": 40,
                                                "rotation_sigma_urad": 100}).json()
    for a, b in zip(one["joints"], two["joints"], strict=True):
        assert a["std_Nm_per_rad"] == pytest.approx(a["predicted_se_Nm_per_rad"], rel=0.1)
        assert b["predicted_se_Nm_per_rad"] == pytest.approx(
            2 * a["predicted_se_Nm_per_rad"], rel=0.02)


def test_sensitivity_from_a_plan_uses_its_poses_and_wrenches(client):
    got = client.post("/api/sensitivity", json={**SMALL, "poses": "plan", "plan": "plan",
                                                "n_tests": 5}).json()
    assert np.allclose(got["q_deg"][0], POSES_DEG[0])
    assert np.allclose(got["q_deg"][3], got["q_deg"][0])  # 3 plan tests, cycled
    assert np.allclose(got["wrench_N_Nm"][1], [0, 2200, 2200, 200, 200, 0])


def test_sensitivity_typed_poses_and_robot_file(client):
    got = client.post("/api/sensitivity", json={
        **SMALL, "robot": "robot.toml", "poses": "typed",
        "q_deg": POSES_DEG[:2]}).json()
    assert got["robot"] == "KUKA KR240-2" and len(got["q_deg"]) == 6
    assert np.allclose(got["q_deg"][2], POSES_DEG[0])


@pytest.mark.parametrize("field,value", [
    ("plan", "../outside"), ("plan", "/etc"), ("plan", "plan/../../x"),
    ("robot", "../robot.toml"), ("robot", "/etc/passwd.toml"), ("robot", "link.toml"),
    ("plan", "linkdir"),
])
def test_paths_outside_the_workspace_are_refused(client, workspace, field, value):
    (workspace / "link.toml").symlink_to(workspace / "robot.toml")
    (workspace / "linkdir").symlink_to(workspace / "plan")
    body = {**SMALL, field: value, "poses": "plan" if field == "plan" else "zones"}
    if field == "robot":
        body.pop("plan", None)
    r = client.post("/api/sensitivity", json=body)
    assert r.status_code == 422, r.text
    assert any(w in r.json()["detail"] for w in ("'..'", "absolute", "symbolic link"))


def test_bad_settings_are_422_with_the_field(client):
    for body, word in [({"trials": 1}, "trials"), ({"method": "lsq"}, "method"),
                       ({"wrench_N_Nm": [0] * 6}, "wrench"), ({"robot": "kr999"}, "robot"),
                       ({"poses": "typed", "q_deg": [[0, 0, 0]]}, "q"),
                       ({"poses": "typed", "q_deg": [[0, -10, 0, 0, 0, 0]]},
                        "pose 1: q2 = -10 deg is outside the joint limits [0, 146] deg"),
                       ({"translation_sigma_um": -1}, "translation_sigma_um")]:
        r = client.post("/api/sensitivity", json={**SMALL, **body})
        assert r.status_code == 422 and word in r.json()["detail"], (body, r.text)


def test_runs_lists_plan_run_and_analysis(client, workspace):
    import json

    run = workspace / "runs" / "r1"
    (run / "analysis").mkdir(parents=True)
    (run / "metadata.json").write_text(json.dumps({
        "status": "aborted", "reason": "Ctrl-C", "started_utc": "2026-01-02T03:04:05+00:00",
        "robot": {"name": "KUKA KR240-2"}, "n_planned_tests": 4}))
    (run / "tests.csv").write_text("h\n1\n2\n")
    (run / "analysis" / "results.json").write_text(json.dumps({
        "robot": "KUKA KR240-2", "method": "ols", "n_tests": 2,
        "joint_stiffness_Nm_per_rad": [1.0e6, 2.0e5], "ci95_Nm_per_rad": [[9e5, 1.1e6],
                                                                          [1e5, 3e5]]}))
    (workspace / "plan" / "summary.json").write_text(json.dumps({
        "robot": "KUKA KR240-2", "tests": [1, 2, 3], "strategy": "worst-joint",
        "predicted_standard_errors": [{"joint": 1, "k_prior_N_m_per_rad": 1.4e6,
                                       "se_design_N_m_per_rad": 3e3}]}))
    (workspace / ".hidden").mkdir()
    (workspace / ".hidden" / "metadata.json").write_text("{}")
    entries = {(e["kind"], e["path"]): e for e in client.get("/api/runs").json()}
    assert set(entries) == {("plan", "plan"), ("run", "runs/r1"),
                            ("analysis", "runs/r1/analysis")}
    assert entries[("run", "runs/r1")]["status"] == "aborted"
    assert "2 test rows measured, 4 tests planned; Ctrl-C" == entries[("run", "runs/r1")]["detail"]
    assert entries[("analysis", "runs/r1/analysis")]["k"][1]["k_Nm_per_rad"] == 2.0e5
    table = client.get("/api/runs/table").text
    # the report's k format: no thousands comma inside an interval
    assert "k1 = 1000.0 [900.00, 1100.0]" in table and "k1 = 1400.0 \u00b1 3.0" in table


def test_runs_reports_an_unreadable_file(client, workspace):
    (workspace / "bad").mkdir()
    (workspace / "bad" / "metadata.json").write_text("{not json")
    e = [e for e in client.get("/api/runs").json() if e["path"] == "bad"]
    assert e and e[0]["status"] == "unreadable" and "metadata.json" in e[0]["detail"]


def test_openapi_document_lists_the_routes(client):
    doc = client.get("/openapi.json").json()
    assert "/api/sensitivity" in doc["paths"] and "/api/runs" in doc["paths"]
    props = doc["components"]["schemas"]["SensitivityRequest"]["properties"]
    assert props["n_tests"]["maximum"] == 200


def test_predicted_curve_falls_with_the_tests_and_matches_the_table(client):
    got = client.post("/api/sensitivity", json={**SMALL, "method": "wls"}).json()
    curve = np.array(got["curve_relative_se"], dtype=float)
    assert got["curve_tests"][0] == 1 and len(curve) == len(got["curve_tests"]) >= 40
    finite = curve[np.all(np.isfinite(curve), axis=1)]
    assert len(finite) > 30 and np.all(np.diff(finite, axis=0) <= 1e-12)  # information adds
    for c, j in enumerate(got["joints"]):
        assert curve[SMALL["n_tests"] - 1, c] * j["k_true_Nm_per_rad"] == pytest.approx(
            j["predicted_se_Nm_per_rad"], rel=1e-12)


def test_reflector_radius_sets_the_rotation_sigma(client):
    """sigma_rot = sqrt(2) * sigma_point * sqrt(2/3) / rho: halving rho doubles it."""
    from analysis.identification.noise import NoiseModel

    a = client.post("/api/sensitivity", json={**SMALL, "reflector_radius_mm": 100}).json()
    b = client.post("/api/sensitivity", json={**SMALL, "reflector_radius_mm": 50}).json()
    expect = np.sqrt(2) * NoiseModel().point_sigma * np.sqrt(2 / 3) / 0.1 * 1e6
    assert a["noise"]["rotation_sigma_urad"] == pytest.approx(expect, rel=1e-12)
    assert b["noise"]["rotation_sigma_urad"] == pytest.approx(2 * expect, rel=1e-12)
    c = client.post("/api/sensitivity", json={**SMALL, "reflector_radius_mm": 50,
                                              "rotation_sigma_urad": 7}).json()
    assert c["noise"]["rotation_sigma_urad"] == pytest.approx(7)  # the sigma wins


def test_predicted_se_is_the_planners_for_its_plan(client, workspace):
    """The explorer on a plan `campaign plan` wrote, with the plan's noise figures and
    as many tests as the plan's rows, predicts the plan's own standard errors."""
    import json
    import subprocess
    import sys
    from pathlib import Path

    import pandas as pd

    root = Path(__file__).resolve().parents[2]
    out = workspace / "planned"
    subprocess.run([sys.executable, "-m", "campaign", "plan", "--protocol",
                    str(root / "protocols" / "kr240-2.toml"), "--out", str(out),
                    "--no-figure", "--candidates", "500"], check=True, capture_output=True,
                   timeout=120)
    summary = json.loads((out / "summary.json").read_text())
    repeats = pd.read_csv(out / "plan.csv")["repeats"]
    assert repeats.nunique() == 1  # cycling the tests then gives the plan's rows
    nz = summary["noise_model_per_row"]
    body = {"poses": "plan", "plan": "planned", "trials": 20, "n_tests": int(repeats.sum()),
            "translation_sigma_um": nz["translation_sigma_um"],
            "rotation_sigma_urad": nz["rotation_sigma_urad"],
            "force_sigma_N": nz["force_sigma_N"], "moment_sigma_Nm": nz["moment_sigma_Nm"],
            "force_percent": nz["force_relative_percent"],
            "moment_percent": nz["moment_relative_percent"],
            "encoder_resolution_deg": nz["joint_sigma_deg"] * np.sqrt(12)}
    got = client.post("/api/sensitivity", json=body).json()
    for j, want in zip(got["joints"], summary["predicted_standard_errors"], strict=True):
        assert j["k_true_Nm_per_rad"] == want["k_prior_N_m_per_rad"]
        assert j["predicted_se_Nm_per_rad"] == pytest.approx(want["se_design_N_m_per_rad"],
                                                             rel=1e-9)


def test_runs_file_serves_workspace_files_only(client, workspace, tmp_path):
    (workspace / "plan" / "summary.txt").write_text("5 tests\n")
    (workspace / "plan" / "summary.json").write_text('{"robot": "KUKA KR240-2"}')
    (workspace / "plan" / "report.html").write_text("<p>report</p>")
    secret = tmp_path / "secret.txt"
    secret.write_text("outside")
    (workspace / "plan" / "leak.txt").symlink_to(secret)
    r = client.get("/api/runs/file", params={"path": "plan/summary.txt"})
    assert r.status_code == 200 and r.text == "5 tests\n"
    r = client.get("/api/runs/file", params={"path": "plan/report.html"})
    assert "sandbox" in r.headers["content-security-policy"]
    for bad, word in [("../secret.txt", "'..'"), (str(secret), "absolute"),
                      ("plan/leak.txt", "symbolic link"), ("plan/plan.csv.exe", "only"),
                      ("plan/missing.txt", "no such file"), ("robot.toml/..", "'..'")]:
        r = client.get("/api/runs/file", params={"path": bad})
        assert r.status_code == 422 and word in r.json()["detail"], (bad, r.text)
    assert "outside" not in client.get("/api/runs/table").text
    table = client.get("/api/runs/table").text
    assert "/api/runs/file?path=plan/summary.txt" in table
    assert "leak" not in table
