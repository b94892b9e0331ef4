"""A plan made in the GUI with a workspace robot file or URDF can be acquired and analysed:
the plan directory's protocol copy names its robot file beside it (campaign.protocol_copy),
and so does the run directory's, so each is self-contained."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from tests.web.conftest import post_followed
from tests.web.test_robot_pickers import K, arm_urdf

pytestmark = pytest.mark.timeout(180)
#: the simulated lab's clock runs this much faster than the wall clock
FAST = 500.0


@pytest.fixture
def robot_ws(workspace: Path) -> Path:
    from analysis.model.robots import builtin_files

    (workspace / "robots").mkdir()
    shutil.copy(builtin_files()["kr240-2"], workspace / "robots" / "x.toml")
    (workspace / "robots" / "arm.urdf").write_text(arm_urdf())
    return workspace


def _plan(client, robot: str, name: str) -> dict:
    r = post_followed(client, "/api/plan/run", json={"values": {
        "campaign.robot": robot, "campaign.tests": "3", "campaign.repeats": "1"},
        "candidates": 200, "name": name})
    assert r.status_code == 200, r.text
    return r.json()


def test_gui_plan_with_a_workspace_robot_file_is_acquired_and_analysed(client, robot_ws,
                                                                      tmp_path):
    from campaign.jobs.acquire import AcquireJobOptions
    from campaign.jobs.acquire import run as acquire
    from campaign.jobs.analyze import AnalyzeOptions
    from campaign.jobs.analyze import run as analyze
    from campaign.protocol import load_protocol

    d = _plan(client, "../robots/x.toml", "px")
    assert d["warnings"] == []
    plan_dir = robot_ws / "plans" / "px"
    copy = load_protocol(plan_dir / "protocol.toml")
    assert copy.campaign.robot == "x.toml"
    assert (plan_dir / "x.toml").read_bytes() == (robot_ws / "robots" / "x.toml").read_bytes()
    # the saved protocol keeps the path the user gave
    assert load_protocol(robot_ws / "protocols" / "px.toml").campaign.robot == "../robots/x.toml"

    run_dir = robot_ws / "runs" / "rx"
    got = acquire(AcquireJobOptions(plan=plan_dir, out=run_dir, fake=True, assume_yes=True,
                                    time_scale=FAST),
                  say=lambda s: None)
    assert got.status == "complete" and got.ok == 3, got
    assert (run_dir / "x.toml").is_file()
    assert load_protocol(run_dir / "protocol.toml").campaign.robot == "x.toml"
    first = analyze(AnalyzeOptions(run_dir=run_dir, report=False, accept_misfit=True))
    k = np.array(first.results["joint_stiffness_Nm_per_rad"], float)
    true_k = np.array(copy.fake_lab.true_joint_stiffness, float)  # the simulated robot's
    assert k.shape == (6,) and np.all(np.abs(k / true_k - 1) < 0.10), k / true_k
    # self-contained: moved out of the workspace, with the workspace's robot file gone,
    # the run gives the same k
    moved = tmp_path / "elsewhere" / "rx"
    shutil.copytree(run_dir, moved, ignore=shutil.ignore_patterns("analysis"))
    (robot_ws / "robots" / "x.toml").unlink()
    again = analyze(AnalyzeOptions(run_dir=moved, report=False, accept_misfit=True))
    assert again.results["joint_stiffness_Nm_per_rad"] == list(k)


def test_urdf_with_frame_is_copied_beside_and_reads_the_same_robot(robot_ws):
    """robots/arm.urdf#tool0 named from protocols/: the copy in plans/pu names
    arm.urdf#tool0 beside it and loads the same chain (tool frame 50 mm past joint 6)."""
    from analysis.model.kinematics import tool_pose
    from campaign.protocol import load_protocol
    from campaign.protocol_copy import copy_beside, portable_copy
    from campaign.protocol_robot import protocol_robot

    text = (Path(__file__).parents[2] / "protocols" / "kr240-2.toml").read_text()
    text = text.replace('robot = "kr240-2"', 'robot = "../robots/arm.urdf#tool0"\n'
                        'prior_stiffness = [1e6, 1e6, 1e6, 1e5, 1e5, 1e5]')
    (robot_ws / "protocols").mkdir()
    (robot_ws / "protocols" / "pu.toml").write_text(text)
    proto = load_protocol(robot_ws / "protocols" / "pu.toml")
    copy_text, files = portable_copy(proto)
    assert copy_text == text.replace("../robots/arm.urdf#tool0", "arm.urdf#tool0")
    plan_dir = robot_ws / "plans" / "pu"
    plan_dir.mkdir(parents=True)
    (plan_dir / "protocol.toml").write_text(copy_text)
    copy_beside(files, plan_dir)
    assert (plan_dir / "arm.urdf").read_text() == arm_urdf()
    copy = load_protocol(plan_dir / "protocol.toml")
    a, b = protocol_robot(proto), protocol_robot(copy)
    q = np.radians([10.0, -20.0, 30.0, 40.0, -50.0, 60.0])
    assert b.n == 6 and np.allclose(tool_pose(a, q), tool_pose(b, q), atol=1e-12)
    # a copy of the copy (the run directory's) is unchanged: the name is already bare
    assert portable_copy(copy) == (copy_text, {"arm.urdf": plan_dir / "arm.urdf"})


def test_gui_plan_with_a_workspace_urdf_is_acquired_and_analysed(client, robot_ws):
    """robots/arm.urdf#tool0 (the picker's value from protocols/: ../robots/...), zones and
    thresholds for the small arm as test_robot_pickers plans it; 3 tests of 1 repeat."""
    from campaign.jobs.acquire import AcquireJobOptions
    from campaign.jobs.acquire import run as acquire
    from campaign.jobs.analyze import AnalyzeOptions
    from campaign.jobs.analyze import run as analyze

    values = {"campaign.robot": "../robots/arm.urdf#tool0", "campaign.tests": "3",
              "campaign.repeats": "1", "campaign.prior_stiffness": ", ".join(map(str, K)),
              "campaign.characteristic_length_mm": "800",
              "sampling.use_robot_zones": "false", "sampling.fixed_deg": "{ q1 = 0 }",
              "zones[0].name": "front", "zones[0].ranges_deg": "{ q2 = [-60, 0], q3 = [20, 90] }",
              "thresholds.min_inv_kappa_F": "0.05", "thresholds.max_v_p": "0.5",
              "thresholds.max_v_r_deg": "5",
              "fake_lab.true_joint_stiffness": ", ".join(map(str, K))}
    r = post_followed(client, "/api/plan/run",
                      json={"values": values, "candidates": 200, "name": "pa"})
    assert r.status_code == 200, r.text
    assert r.json()["warnings"] == []
    plan_dir = robot_ws / "plans" / "pa"
    run_dir = robot_ws / "runs" / "ra"
    got = acquire(AcquireJobOptions(plan=plan_dir, out=run_dir, fake=True, assume_yes=True,
                                    time_scale=FAST), say=lambda s: None)
    assert got.status == "complete" and got.ok == 3, got
    assert (run_dir / "arm.urdf").read_text() == arm_urdf()
    res = analyze(AnalyzeOptions(run_dir=run_dir, report=False, accept_misfit=True)).results
    k = np.array(res["joint_stiffness_Nm_per_rad"], float)
    assert res["robot"] == "arm"
    assert k.shape == (6,) and np.all(np.abs(k / np.array(K) - 1) < 0.10), k / np.array(K)
