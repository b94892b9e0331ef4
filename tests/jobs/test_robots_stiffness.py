"""robots and stiffness: the CLI (deg at its edge) and the web API (SI) agree."""

from __future__ import annotations

import numpy as np
import pytest

from tests.jobs.conftest import cli_error, cli_json


def test_robots_list_and_one_model_same_from_cli_and_api(ws, client):
    listed = client.post("/api/jobs/robots", json={})
    assert listed.status_code == 200
    assert listed.json() == cli_json(ws, "robots")
    keys = [r["key"] for r in listed.json()["robots"]]
    assert "kr240-2" in keys and len(keys) >= 5
    one = client.post("/api/jobs/robots", json={"name": "kr240-2"}).json()
    assert one == cli_json(ws, "robots", "kr240-2")
    # the KR240-2 file's joint stiffness values (N m/rad), as written there
    assert one["nominal_stiffness_Nm_per_rad"][:4] == [1409800, 400760, 935280, 360000]


def test_robots_unknown_name_same_message(ws, client):
    answer = client.post("/api/jobs/robots", json={"name": "kr999"})
    assert answer.status_code == 400
    assert answer.json()["detail"] == cli_error(ws, "robots", "kr999")
    assert "unknown robot 'kr999'" in answer.json()["detail"]


def test_stiffness_same_result_deg_at_the_cli_si_at_the_api(ws, client):
    q_deg = [10, 80, -100, 20, 30, 40]
    body = {"robot": "kr240-2", "q_rad": np.radians(q_deg).tolist(),
            "tool_xyz_mm": [0, 0, 200], "wrench_N_Nm": [1000, 0, -500, 0, 50, 0]}
    api = client.post("/api/jobs/stiffness", json=body)
    assert api.status_code == 200, api.text
    doc = cli_json(ws, "stiffness", "--robot", "kr240-2", "--q", "10,80,-100,20,30,40",
                   "--tool-xyz-mm", "0,0,200", "--wrench", "1000,0,-500,0,50,0")
    got = api.json()
    assert got.keys() == doc.keys()
    assert got["tool"] == doc["tool"]
    for key in ("q_rad", "J_m_rad_per_rad", "K_C_Nm_per_rad", "K_X", "deflection_m_rad",
                "deflection_nonlinear_m_rad"):
        np.testing.assert_allclose(got[key], doc[key], rtol=1e-12, atol=1e-15)
    # an independent check: the linear deflection is J K_theta^-1 J^T w without K_C
    J, k = np.array(got["J_m_rad_per_rad"]), np.array(got["joint_stiffness_Nm_per_rad"])
    np.testing.assert_allclose(got["deflection_without_K_C_m_rad"],
                               J @ np.diag(1 / k) @ J.T @ np.array(body["wrench_N_Nm"]),
                               rtol=1e-9, atol=1e-15)


#: a pose inside the KR240-2 limits (rad) and as typed at the CLI (deg)
Q_OK = np.radians([0, 60, -60, 0, 30, 0]).tolist()


@pytest.mark.parametrize(("body", "args"), [
    ({"robot": "kr240-2", "q_rad": [0.0, -1.0, 1.0, 0, 0, 0]},
     ["--robot", "kr240-2", "--q",
      f"0,{float(np.degrees(-1.0))!r},{float(np.degrees(1.0))!r},0,0,0"]),
    ({"robot": "kr240-2", "q_rad": [0.0, 1.0, 1.0, 0, 0]},
     ["--robot", "kr240-2", "--q", "0,1,1,0,0"]),
    ({"robot": "kr240-2", "q_rad": Q_OK,
      "joint_stiffness_Nm_per_rad": [1, 1, -1, 1, 1, 1]},
     ["--robot", "kr240-2", "--q", "0,60,-60,0,30,0", "--joint-stiffness", "1,1,-1,1,1,1"]),
    ({"robot": "kr240-2", "q_rad": Q_OK, "tool_xyz_mm": [1, 2]},
     ["--robot", "kr240-2", "--q", "0,60,-60,0,30,0", "--tool-xyz-mm", "1,2"]),
])
def test_stiffness_bad_input_same_line_400(ws, client, body, args):
    answer = client.post("/api/jobs/stiffness", json=body)
    assert answer.status_code == 400
    assert answer.json()["detail"] == cli_error(ws, "stiffness", *args)


@pytest.mark.parametrize("robot", ["../kr.toml", "/etc/kr.toml", "sub/../../kr.toml"])
def test_paths_out_of_the_workspace_refused(client, robot):
    answer = client.post("/api/jobs/stiffness", json={"robot": robot, "q_rad": [0] * 6})
    assert answer.status_code == 400
    assert answer.json()["detail"].startswith("robot: ")


def test_symlink_out_of_the_workspace_refused(ws, client, tmp_path):
    outside = tmp_path / "outside.toml"
    outside.write_text("")
    (ws / "kr.toml").symlink_to(outside)
    answer = client.post("/api/jobs/stiffness", json={"robot": "kr.toml", "q_rad": [0] * 6})
    assert answer.status_code == 400
    assert "leads out of the workspace" in answer.json()["detail"]


def test_schema_errors_are_422_not_500(client):
    answer = client.post("/api/jobs/stiffness", json={"robot": "kr240-2", "q_rad": "abc"})
    assert answer.status_code == 422
