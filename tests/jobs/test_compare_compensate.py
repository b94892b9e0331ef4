"""compare and compensate: the CLI and the web API give the same results and files."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from tests.jobs.conftest import cli, cli_error, cli_json


def test_compare_same_from_cli_and_api(ws, client, campaigns):
    a, b = campaigns
    doc = cli_json(ws, "compare", a, b, "--plot", "cli.png")
    answer = client.post("/api/jobs/compare", json={"a": a, "b": b, "plot": "api.png"})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    assert got.pop("plot") == "api.png" and doc.pop("plot") == "cli.png"
    assert got == doc
    assert (ws / "api.png").stat().st_size > 1000
    # B was simulated with k2 10 % higher: the comparison sees it (k1, correlated with k2
    # in this 5-pose design, may follow), the wrist joints did not change
    k2 = got["joints"][1]
    assert k2["verdict"] == "changed" and k2["z"] > 0
    assert abs(k2["relative_difference"] - 0.10) < 0.05
    assert all(r["verdict"] == "no evidence of change" for r in got["joints"][2:])


def test_compare_refusals_same_line(ws, client, campaigns):
    a, _ = campaigns
    answer = client.post("/api/jobs/compare", json={"a": a, "b": "nowhere"})
    assert answer.status_code == 400
    assert answer.json()["detail"] == cli_error(ws, "compare", a, "nowhere")
    answer = client.post("/api/jobs/compare", json={"a": a, "b": "../B"})
    assert answer.status_code == 400 and answer.json()["detail"].startswith("b: ")


def _path_csv(ws, name="path.csv") -> str:
    """Ten points of a straight joint-space path (model convention, deg), no wrench columns."""
    t = np.linspace(0, 1, 10)[:, None]
    q = np.array([0, 40, -110, 10, 40, 20]) + t * np.array([30, 20, 10, -20, 20, 30])
    frame = pd.DataFrame(q, columns=[f"q{j + 1}_deg" for j in range(6)])
    frame.to_csv(ws / name, index=False)
    return name


def test_compensate_same_files_from_cli_and_api(ws, client, campaigns):
    a, _ = campaigns
    path = _path_csv(ws)
    model = f"{a}/model.toml"
    proc = cli(ws, "compensate", "--robot", model, "--path", path, "--out", "cli",
               "--wrench", "500,0,-1000,0,20,0")
    assert proc.returncode == 0, proc.stderr
    answer = client.post("/api/jobs/compensate", json={
        "robot": model, "path": path, "out": "api", "wrench_N_Nm": [500, 0, -1000, 0, 20, 0]})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    names = sorted(p.name for p in (ws / "cli").iterdir())
    assert names == sorted(p.name for p in (ws / "api").iterdir())
    assert [f.removeprefix("api/") for f in got["files"]] == \
        [line.split("wrote cli/")[1] for line in proc.stdout.splitlines()
         if line.startswith("wrote ")]
    for name in names:  # the API's files name the model by its absolute path
        if not name.endswith(".png"):
            assert (ws / "api" / name).read_text().replace(f"{ws}/", "") == \
                (ws / "cli" / name).read_text(), name
    summary = json.loads((ws / "api" / "summary.json").read_text().replace(f"{ws}/", ""))
    assert summary == {k: v for k, v in got.items() if k != "files"}
    assert summary["points"] == 10
    assert summary["max_residual_m"] < 1e-6  # the compensation closes the model's loop
    table = pd.read_csv(ws / "api" / "compensated.csv")
    assert len(table) == 10


def test_compensate_refusals_same_line(ws, client, campaigns):
    path = _path_csv(ws)
    for body, args in (
        ({"robot": "kr240-2", "path": path, "out": "o", "readings": 0},
         ["--robot", "kr240-2", "--path", path, "--out", "o", "--readings", "0"]),
        ({"robot": "kr240-2", "path": path, "out": "o", "verify_fake": True},
         ["--robot", "kr240-2", "--path", path, "--out", "o", "--verify-fake"]),
        ({"robot": "kr240-2", "path": "missing.csv", "out": "o"},
         ["--robot", "kr240-2", "--path", "missing.csv", "--out", "o"]),
        ({"robot": "kr240-2", "path": path, "out": "o", "wrench_N_Nm": [1, 2, 3]},
         ["--robot", "kr240-2", "--path", path, "--out", "o", "--wrench", "1,2,3"]),
    ):
        answer = client.post("/api/jobs/compensate", json=body)
        assert answer.status_code == 400, answer.text
        assert answer.json()["detail"] == cli_error(ws, "compensate", *args)
    assert not (ws / "o").exists()


def test_path_deflection_is_compensate_before_compensating(ws, app, client, campaigns):
    """One options record and one path reader: path_deflection's prediction, band and
    sources are compensate's (identified model: a covariance, so a band); its refusals of
    the shared fields are compensate's lines."""
    import dataclasses

    from campaign.jobs.compensate import CompensateOptions
    from campaign.jobs.path_deflection import PathDeflectionOptions
    from campaign.web import use_path_api

    app.include_router(use_path_api.router)
    shared = {f.name: f.default for f in dataclasses.fields(PathDeflectionOptions)}
    assert {f.name: f.default for f in dataclasses.fields(CompensateOptions)
            if f.name in shared} == shared
    a, _ = campaigns
    path, model, wrench = _path_csv(ws), f"{a}/model.toml", [500, 0, -1000, 0, 20, 0]
    load = {"wrench_N_Nm": wrench, "wrench_frame": "tool"}
    pd_answer = client.post("/api/use/deflection", json={"robot": model, "path": path, **load})
    comp = client.post("/api/jobs/compensate", json={"robot": model, "path": path, "out": "c",
                                                     **load})
    assert pd_answer.status_code == 200, pd_answer.text
    assert comp.status_code == 200, comp.text
    got, summary = pd_answer.json(), comp.json()
    table = pd.read_csv(ws / "c" / "compensated.csv")
    screw, lo, hi = (np.asarray(got[k]) for k in ("deflection_m_rad", "lo95_m_rad",
                                                   "hi95_m_rad"))
    for j, name in enumerate(["dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"]):
        stem, unit = name.split("_")
        assert np.allclose(1e3 * screw[:, j], table[name], rtol=1e-10, atol=1e-12), name
        assert np.allclose(1e3 * lo[:, j], table[f"{stem}_lo95_{unit}"], rtol=1e-10), name
        assert np.allclose(1e3 * hi[:, j], table[f"{stem}_hi95_{unit}"], rtol=1e-10), name
    assert np.all(hi[:, :3] > lo[:, :3])  # a band of non-zero width
    assert got["joint_stiffness_source"] == "identified (model.toml)"
    assert f"joint stiffness: {got['joint_stiffness_source']}" in summary["assumptions"]
    assert f"wrench: {got['wrench_source']}" in summary["assumptions"]
    # the page shows this source: in words, not the command line's --wrench
    assert got["wrench_source"].startswith("the wrench given (constant)"), got["wrench_source"]
    assert 1e3 * got["max_norm_p_m"] == pytest.approx(
        summary["translation_m"]["before"]["max"] * 1e3, rel=1e-10)
    # a tool point on a built-in robot (nominal k: no band): P moved, the same P in both
    tool = {"robot": "kr240-2", "path": path, "wrench_N_Nm": wrench, "tool_xyz_mm": [0, 0, 150]}
    one = client.post("/api/use/deflection", json=tool).json()
    client.post("/api/jobs/compensate", json={**tool, "out": "t"})
    flange = client.post("/api/use/deflection", json={**tool, "tool_xyz_mm": None}).json()
    dx = pd.read_csv(ws / "t" / "compensated.csv")["dx_mm"]
    assert np.allclose(1e3 * np.asarray(one["deflection_m_rad"])[:, 0], dx, rtol=1e-10)
    assert abs(one["max_norm_p_m"] / flange["max_norm_p_m"] - 1) > 1e-3
    for extra in ({"min_inv_kappa": 0}, {"wrench_N_Nm": [1, 2, 3]},
                  {"joint_stiffness_Nm_per_rad": [1e6] * 5}, {"tool_xyz_mm": [0, 0, 150]}):
        one = client.post("/api/use/deflection", json={"robot": model, "path": path, **extra})
        two = client.post("/api/jobs/compensate", json={"robot": model, "path": path,
                                                        "out": "o", **extra})
        assert one.status_code == two.status_code == 400, (one.text, two.text)
        assert one.json()["detail"] == two.json()["detail"], extra
        # the identified model refuses a second tool point: on its robot
        assert one.json()["field"] == two.json()["field"] == \
            ("robot" if "tool_xyz_mm" in extra else next(iter(extra))), extra
    assert not (ws / "o").exists()
