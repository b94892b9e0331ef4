"""Refusals before any motion, the dry run, bad input; settling, approach poses, checks."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot
from campaign.acquire.checks import Limits, evaluate
from campaign.acquire.geometry import approach_pose, displacement
from campaign.acquire.settle import SettleRule, half_difference, rule_for, wait_settled
from drivers.errors import DeviceTimeout


def test_plan_outside_the_limits_is_refused_before_any_motion(kr240_plan, make_variant,
                                                             tmp_path, cli):
    def bad(df):
        df.loc[df.index[2], "q2_model_deg"] = 1.0  # limit 0 deg, margin 2 deg
        return df

    plan = make_variant(kr240_plan, tmp_path / "plan", edit=bad)
    run = tmp_path / "run"
    res = cli("acquire", "--plan", str(plan), "--out", str(run), "--fake", "--yes")
    assert res.returncode == 2
    assert "refused before any motion" in res.stderr
    assert "joint 2" in res.stderr and "test 3" in res.stderr
    assert "Traceback" not in res.stderr
    assert not run.exists()  # nothing written, nothing connected, nothing moved


def test_load_above_the_force_limit_is_refused(kr240_plan, make_variant, tmp_path, cli):
    def heavy(df):
        df.loc[df.index[0], "fz_N"] = 5000.0
        return df

    plan = make_variant(kr240_plan, tmp_path / "plan", edit=heavy)
    res = cli("acquire", "--plan", str(plan), "--dry-run")
    assert res.returncode == 2 and "test 1" in res.stderr and "above the limit" in res.stderr


def test_dry_run_lists_every_target_and_touches_nothing(kr240_plan, tmp_path, cli):
    res = cli("acquire", "--plan", str(kr240_plan), "--dry-run", "--out", str(tmp_path / "r"))
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert any(line.startswith("1a ") for line in lines)
    assert sum(line.split()[0] in {str(i) for i in range(1, 6)} for line in lines
               if line.strip()) == 5
    assert "speed limit 10.0 deg/s" in res.stdout
    assert "nothing connected, nothing moved" in res.stdout
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("args, text", [
    (["--time-scale", "10"], "--time-scale"),
    (["--quiet", "--json"], "--quiet"),
])
def test_bad_options_are_clear_errors(kr240_plan, cli, args, text):
    res = cli("acquire", "--plan", str(kr240_plan), "--dry-run", *args)
    assert res.returncode == 2 and text in res.stderr and "Traceback" not in res.stderr


def test_resume_of_something_that_is_not_a_run(tmp_path, cli):
    res = cli("acquire", "--resume", str(tmp_path), "--fake", "--yes")
    assert res.returncode == 2 and "metadata.json" in res.stderr


def test_without_yes_a_refusal_moves_nothing(kr240_plan, tmp_path):
    from analysis.errors import InputError
    from campaign.acquire.progress import QuietReporter
    from campaign.acquire.session import AcquireOptions, acquire

    with pytest.raises(InputError, match="not confirmed"):
        acquire(kr240_plan, tmp_path / "run", None, AcquireOptions(fake=True),
                QuietReporter(), say=lambda s: None, ask=lambda prompt: "no")
    assert not (tmp_path / "run").exists()


def test_settling_detection_on_an_exponential_with_noise():
    rng = np.random.default_rng(3)
    tau, sigma, amplitude = 0.5, 30e-6, 5e-3  # s, m, m
    rule = rule_for(sigma, time_scale=1.0, settle_scale=tau)
    clock = {"t": 0.0}

    def read():
        return np.array([amplitude * np.exp(-clock["t"] / tau), 0, 0]) + \
            rng.normal(0, sigma, 3)

    def sleep(dt):
        clock["t"] += dt

    points, n = wait_settled(read, rule, clock=lambda: clock["t"], sleep=sleep)
    left = amplitude * np.exp(-clock["t"] / tau)
    assert left < sigma / 3  # what is still to come is well below the tracker noise
    assert clock["t"] < 12 * tau  # and it did not wait forever
    assert n >= rule.window and half_difference(points) < rule.tolerance


def test_settling_times_out_on_a_drifting_tool():
    clock = {"t": 0.0}
    rule = SettleRule(interval=0.1, window=4, tolerance=1e-6, timeout=2.0)

    def sleep(dt):
        clock["t"] += dt

    with pytest.raises(DeviceTimeout, match="still moving"):
        wait_settled(lambda: np.array([1e-3 * clock["t"], 0, 0]), rule,
                     clock=lambda: clock["t"], sleep=sleep)


def test_approach_pose_is_the_offset_away_with_the_same_orientation():
    robot = load_robot("kr240-2")
    q = np.deg2rad([0, 50.911, -184.273, 45, 45, 45])
    qa = approach_pose(robot, q, 0.100, np.deg2rad(2))
    T, Ta = tool_pose(robot, q), tool_pose(robot, qa)
    assert np.isclose(np.linalg.norm(Ta[:3, 3] - T[:3, 3]), 0.100, atol=1e-6)
    assert np.allclose(Ta[:3, :3], T[:3, :3], atol=1e-8)
    # at q2 = 3 deg (limit 0 deg, margin 2 deg) it finds a direction that keeps q2 >= 2 deg
    q_edge = np.deg2rad([0, 3.0, -170.0, 45, 45, 45])
    qe = approach_pose(robot, q_edge, 0.100, np.deg2rad(2))
    assert robot.within_limits(qe, np.deg2rad(2))


def test_displacement_is_expressed_in_the_base_frame():
    from drivers.frames import rotvec_to_matrix

    R = rotvec_to_matrix([0.1, -0.4, 0.5])  # base frame seen from the tracker
    T0 = np.eye(4)
    T1 = np.eye(4)
    T1[:3, :3] = rotvec_to_matrix(R @ np.array([1e-3, 0, 0]))
    T1[:3, 3] = R @ np.array([0.002, 0, -0.001])
    s = displacement(T0, T1, R)
    assert np.allclose(s, [0.002, 0, -0.001, 1e-3, 0, 0], atol=1e-12)


def test_checks_flag_each_failure():
    lim = Limits(repeatability=0.36e-3, drift=0.6e-3, wrench_abs=5, wrench_rel=0.05,
                 tracker=0.12e-3, force_range=2500, moment_range=None)
    w = np.array([0, 2200, 2200, 200, 200, 0.0])
    ok = evaluate(lim, np.zeros(3), np.array([1e-4, 0, 0]), np.zeros(3), w, w, w, [5e-5])
    assert ok.flags == () and np.isclose(ok.repeatability, 1e-4)
    bad = evaluate(lim, np.zeros(3), np.array([1e-3, 0, 0]), np.array([0, 0, 1e-3]),
                   w + [200, 0, 0, 0, 0, 0], w, np.array([0, 2480, 0, 0, 0, 0]), [2e-4, None])
    assert set(bad.flags) == {"repeatability", "drift", "wrench_mismatch",
                              "tracker_uncertainty", "saturation"}
    assert np.isclose(bad.wrench_error, 200)
    json.dumps(bad.flags)


@pytest.mark.parametrize("mode", ["--json", "--quiet", None])
def test_confirmation_shows_the_motions_and_refuses_without_yes(kr240_plan, tmp_path, mode):
    """Without --yes the motion list and the question reach the operator (stderr in the
    machine-readable modes, so stdout stays parseable); anything but 'yes' refuses, exit 2,
    and nothing is created."""
    import subprocess
    import sys

    from tests.acquire.conftest import ROOT

    out = tmp_path / "run"
    args = [sys.executable, "-m", "campaign", "acquire", "--plan", str(kr240_plan), "--fake",
            "--out", str(out)] + ([mode] if mode else [])
    proc = subprocess.run(args, input="no\n", capture_output=True, text=True, timeout=120,
                          cwd=ROOT)
    assert proc.returncode == 2
    shown = proc.stderr if mode else proc.stdout
    assert "Type 'yes' to move the robot" in proc.stderr + proc.stdout
    assert "5a" in shown and "not confirmed" in proc.stderr
    if mode == "--json":
        assert "Type 'yes'" not in proc.stdout
    assert not out.exists()
