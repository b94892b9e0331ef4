"""URDF robots in the GUI's pickers: /api/robots, the upload, the jobs they feed.

A small six-joint URDF written here is offered next to the built-in robots and robot
files, read by the command line's URDF reader, and gives the same numbers through the
API (and the page) as the sensitivity job run directly on the file.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.web.conftest import (
    TOKEN,  # noqa: F401  (the fixtures' token)
    post_followed,
)

#: joint origins (m) and axes of a 6R arm (anthropomorphic, spherical-ish wrist)
JOINTS = [((0, 0, 0.4), (0, 0, 1)), ((0.1, 0, 0.3), (0, 1, 0)), ((0, 0, 0.7), (0, 1, 0)),
          ((0.5, 0, 0.1), (1, 0, 0)), ((0.3, 0, 0), (0, 1, 0)), ((0.1, 0, 0), (1, 0, 0))]
K = [1.2e6, 9.0e5, 6.0e5, 2.0e5, 1.5e5, 1.0e5]


def arm_urdf(name: str = "arm") -> str:
    """The URDF text of the test arm, tool frame ``tool0`` 50 mm past joint 6."""
    links = "".join(f'<link name="link{i}"/>' for i in range(7)) + '<link name="tool0"/>'
    joints = ""
    for i, (xyz, axis) in enumerate(JOINTS, 1):
        joints += (f'<joint name="j{i}" type="revolute"><parent link="link{i - 1}"/>'
                   f'<child link="link{i}"/><origin xyz="{" ".join(map(str, xyz))}" rpy="0 0 0"/>'
                   f'<axis xyz="{" ".join(map(str, axis))}"/>'
                   '<limit lower="-2.9" upper="2.9" effort="100" velocity="1"/></joint>')
    joints += ('<joint name="flange" type="fixed"><parent link="link6"/><child link="tool0"/>'
               '<origin xyz="0.05 0 0" rpy="0 0 0"/></joint>')
    return f'<?xml version="1.0"?><robot name="{name}">{links}{joints}</robot>'


@pytest.fixture
def urdf_ws(workspace: Path) -> Path:
    (workspace / "robots").mkdir()
    (workspace / "robots" / "arm.urdf").write_text(arm_urdf())
    return workspace


def test_robot_spec_with_frame_is_the_tip_option(urdf_ws):
    from analysis.errors import InputError
    from analysis.model.kinematics import tool_pose
    from analysis.model.robots import load_robot

    path = str(urdf_ws / "robots" / "arm.urdf")
    a, b = load_robot(f"{path}#tool0"), load_robot(path, tip="tool0")
    q = np.array([0.1, -0.4, 0.7, 0.3, -0.5, 0.9])
    assert a.n == 6
    assert np.allclose(tool_pose(a, q), tool_pose(b, q), atol=1e-12)
    # tool0 is 50 mm past joint 6 along x6: at q = 0, x = 0.1 + 0.5 + 0.3 + 0.1 + 0.05
    assert tool_pose(a, np.zeros(6))[:3, 3] == pytest.approx([1.05, 0, 1.5])
    with pytest.raises(InputError, match="two tool frames"):
        load_robot(f"{path}#tool0", tip="link6")


def test_pickers_offer_builtin_files_and_urdf_frames(client, urdf_ws):
    from analysis.model.robots import builtin_names

    got = client.get("/api/robots").json()
    values = {c["value"]: c["kind"] for c in got["robots"]}
    assert {n for n, k in values.items() if k == "builtin"} == set(builtin_names())
    assert values["robot.toml"] == "file"
    # tool0 first (a tool frame), then the other frame ending the six-joint chain
    urdf = [c["value"] for c in got["robots"] if c["kind"] == "urdf"]
    assert urdf == ["robots/arm.urdf#tool0", "robots/arm.urdf#link6"]
    assert got["max_upload_bytes"] == 1_000_000
    # the Plan form offers them relative to protocols/, where it saves the protocol
    form = client.get("/api/plan/form").json()
    robot = next(f for f in form["fields"] if f["key"] == "campaign.robot")
    assert "../robots/arm.urdf#tool0" in robot["suggestions"] and "kr240-2" in robot["suggestions"]
    address = next(f for f in form["fields"] if f["key"] == "instruments.*.address")
    assert {"socket://192.168.1.10:700", "manual://", "ur://192.168.1.20"} <= set(
        address["suggestions"])
    driver = next(f for f in form["fields"] if f["key"] == "instruments.*.driver")
    from drivers.registry import available_drivers

    assert driver["suggestions"] == sorted(available_drivers())


def test_upload_reads_with_the_cli_reader_and_refuses_bad_files(client, workspace):
    from analysis.errors import InputError
    from analysis.model.robots import load_robot

    r = client.post("/api/robots/urdf", json={"name": "up.urdf", "text": arm_urdf("up")})
    assert r.status_code == 200, r.text
    assert r.json()["saved"] == "robots/up.urdf"
    assert [c["value"] for c in r.json()["robots"]] == ["robots/up.urdf#tool0",
                                                      "robots/up.urdf#link6"]
    assert (workspace / "robots" / "up.urdf").read_text() == arm_urdf("up")
    again = client.post("/api/robots/urdf", json={"name": "up.urdf", "text": arm_urdf()})
    assert again.status_code == 400 and again.json()["field"] == "name"
    # a broken file: the command line's message, naming the file as saved
    bad = arm_urdf().replace("</robot>", "")
    r = client.post("/api/robots/urdf", json={"name": "bad.urdf", "text": bad})
    assert r.status_code == 400 and r.json()["field"] == "urdf"
    p = workspace / "cli" / "bad.urdf"
    p.parent.mkdir()
    p.write_text(bad)
    with pytest.raises(InputError) as err:
        load_robot(str(p), tip="tool0")
    assert r.json()["detail"] == str(err.value).replace(str(p), "robots/bad.urdf")
    assert r.json()["detail"].startswith("robots/bad.urdf:1: not well-formed XML: ")
    # a joint naming an undefined link: the line of that <child>
    lines = arm_urdf().replace("><", ">\n<").replace('<link name="link3"/>', "")
    r = client.post("/api/robots/urdf", json={"name": "bad.urdf", "text": lines})
    line = next(i for i, t in enumerate(lines.splitlines(), 1) if '<child link="link3"/>' in t)
    assert r.json()["detail"] == (f"robots/bad.urdf:{line}: joint 'j3': child link 'link3' "
                                  "is not defined (no <link name=...> of that name)")
    assert not (workspace / "robots" / "bad.urdf").exists()
    assert [f.name for f in (workspace / "robots").iterdir()] == ["up.urdf"]  # no leftovers
    r = client.post("/api/robots/urdf", json={"name": "up2.urdf", "text": arm_urdf(),
                                              "tip": "nope"})
    assert r.status_code == 400 and r.json()["field"] == "tip" and "nope" in r.json()["detail"]
    for name in ("../x.urdf", "x.toml", ".hidden.urdf"):
        assert client.post("/api/robots/urdf", json={"name": name, "text": "x"}
                           ).json()["field"] == "name"
    big = client.post("/api/robots/urdf", json={"name": "big.urdf", "text": "x" * 1_000_001})
    assert big.status_code == 400  # the line names the file and the limit
    assert big.json()["detail"] == "big.urdf: 1000001 bytes; at most 1000000 bytes"


def test_resolve_robot_keeps_files_inside_the_workspace(urdf_ws):
    from analysis.errors import InputError
    from campaign.web.robots_api import resolve_robot

    assert resolve_robot(urdf_ws, "kr240-2") == "kr240-2"
    assert resolve_robot(urdf_ws, "robots/arm.urdf#tool0") == \
        f"{urdf_ws.resolve()}/robots/arm.urdf#tool0"
    for bad in ("../arm.urdf#tool0", "/etc/arm.urdf#tool0", "/etc/robot.toml"):
        with pytest.raises(InputError):
            resolve_robot(urdf_ws, bad)


def _direct_sensitivity(ws: Path, errors=None, **kw) -> dict:
    from campaign.jobs.sensitivity import ErrorSources, SensitivityOptions, run_sensitivity

    o = SensitivityOptions(robot=f"{ws.resolve()}/robots/arm.urdf#tool0",
                           joint_stiffness=np.array(K), errors=errors or ErrorSources(), **kw)
    return json.loads(json.dumps(run_sensitivity(o).to_dict()))


def test_sensitivity_api_on_a_urdf_equals_the_job(client, urdf_ws):
    r = client.post("/api/sensitivity", json={"robot": "robots/arm.urdf#tool0", "trials": 40,
                                              "joint_stiffness_Nm_per_rad": K, "n_tests": 8})
    assert r.status_code == 200, r.text
    got = r.json()
    want = _direct_sensitivity(urdf_ws, trials=40, n_tests=8)
    assert got["joints"] == want["joints"] and got["q_deg"] == want["q_deg"]
    assert [j["k_true_Nm_per_rad"] for j in got["joints"]] == K
    # a URDF without its frame: the reader's message, naming the field
    r = client.post("/api/sensitivity", json={"robot": "robots/arm.urdf", "trials": 40,
                                              "joint_stiffness_Nm_per_rad": K})
    assert r.status_code == 422 and "tool frame" in r.json()["detail"]
    assert client.post("/api/sensitivity", json={"robot": "../arm.urdf#tool0"}
                       ).status_code == 422


def test_plan_form_plans_a_urdf_robot(client, urdf_ws):
    values = {"campaign.robot": "../robots/arm.urdf#tool0", "campaign.tests": "4",
              "campaign.prior_stiffness": ", ".join(map(str, K)),
              "campaign.characteristic_length_mm": "800",
              "sampling.use_robot_zones": "false", "sampling.fixed_deg": "{ q1 = 0 }",
              "zones[0].name": "front", "zones[0].ranges_deg": "{ q2 = [-60, 0], q3 = [20, 90] }",
              "thresholds.min_inv_kappa_F": "0.05", "thresholds.max_v_p": "0.5",
              "thresholds.max_v_r_deg": "5",
              "fake_lab.true_joint_stiffness": ", ".join(map(str, K))}
    r = post_followed(client, "/api/plan/run",
                      json={"values": values, "candidates": 300, "name": "u"})
    assert r.status_code == 200, r.text
    d = r.json()
    assert d["summary"]["robot"] == "arm" and d["summary"]["tests"] == 4
    assert [row["zone"] for row in d["rows"]] == ["front"] * 4
    # the plan's protocol copy sits one directory deeper: it names the URDF copied beside it
    assert d["warnings"] == []
    assert 'robot = "arm.urdf#tool0"' in (urdf_ws / "plans" / "u" / "protocol.toml").read_text()
    assert (urdf_ws / "plans" / "u" / "arm.urdf").read_text() == arm_urdf()
    assert all(-60 <= row["q2_model_deg"] <= 0 and 20 <= row["q3_model_deg"] <= 90
               for row in d["rows"])


# ---- the page ----

@pytest.fixture
def page_of(server, open_url):
    page = open_url(server)
    page.wait_for_selector("#row-k6", timeout=60_000)
    return page


def test_page_offers_an_uploaded_urdf_and_shows_the_jobs_numbers(page_of, workspace, tmp_path):
    page = page_of
    f = tmp_path / "arm.urdf"
    f.write_text(arm_urdf())
    page.fill("#trials", "60")
    page.fill("#joint_k", ", ".join(map(str, K)))  # a URDF has no published stiffness
    page.set_input_files("#urdf-file", str(f))
    page.click("#urdf-upload")
    page.wait_for_function("() => document.getElementById('urdf-msg').dataset.state === 'saved'")
    offered = page.eval_on_selector_all("#robots option", "os => os.map(o => o.value)")
    assert "robots/arm.urdf#tool0" in offered and "kr240-2" in offered
    assert page.input_value("#robot") == "robots/arm.urdf#tool0"
    page.wait_for_function(
        "k => { const s = document.body.dataset.shown || ''; if (!s.startsWith('{')) return false;"
        " const d = JSON.parse(s); return d.robot === 'robots/arm.urdf#tool0' && d.trials === 60"
        " && JSON.stringify(d.joint_stiffness_Nm_per_rad) === JSON.stringify(k); }", arg=K,
        timeout=60_000)
    shown = json.loads(page.evaluate("() => document.body.dataset.shown"))
    want = _direct_sensitivity(workspace, trials=60, n_tests=shown["n_tests"],
                               method=shown["method"],
                               wrench=np.array(shown["wrench_N_Nm"]), **_noise(shown))
    for j in want["joints"]:
        row = page.locator(f"#row-k{j['joint']}")
        assert float(row.locator("td.median").inner_text()) == pytest.approx(
            j["median_Nm_per_rad"], abs=0.51)
        assert float(row.locator("td.std").inner_text()) == pytest.approx(
            j["std_Nm_per_rad"], abs=0.51)


def _noise(shown: dict) -> dict:
    """The job's error sources for the page's slider values (the API's conversion)."""
    from campaign.jobs.sensitivity import ErrorSources

    def get(key, f):
        return None if shown.get(key) is None else shown[key] * f

    return {"errors": ErrorSources(
        translation_sigma=get("translation_sigma_um", 1e-6),
        rotation_sigma=get("rotation_sigma_urad", 1e-6),
        force_sigma=shown.get("force_sigma_N"), moment_sigma=shown.get("moment_sigma_Nm"),
        force_relative=get("force_percent", 0.01), moment_relative=get("moment_percent", 0.01),
        encoder_resolution=get("encoder_resolution_deg", np.pi / 180),
        reflector_radius=get("reflector_radius_mm", 1e-3))}


def test_use_views_robot_job_takes_a_picker_urdf(client, urdf_ws):
    r = client.post("/api/jobs/robots", json={"name": "robots/arm.urdf#tool0"})
    assert r.status_code == 200, r.text
    d = r.json()
    assert (d["name"], d["joints"], d["convention"]) == ("arm", 6, "urdf")
    assert d["lower_rad"] == [-2.9] * 6 and d["upper_rad"] == [2.9] * 6
    assert client.post("/api/jobs/robots", json={"name": "../arm.urdf#tool0"}).status_code == 400
