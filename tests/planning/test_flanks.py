"""The planner's gear-flank count (campaign.planning.flanks) against the simulated lab's
lost motion, and the preload fraction that keeps every joint on one flank."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.kinetostatics import realistic as R
from analysis.model.gravity import gravity_torques
from analysis.model.kinematics import pin_jacobian
from analysis.model.robots import load_robot
from campaign.planning.flanks import flank_changes, keeping_preload

BAND = np.array([2e-4, 2e-4, 2e-4, 4e-4, 4e-4, 4e-4])


@pytest.fixture(scope="module")
def setup():
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(7)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    q = rng.uniform(lo, hi, (40, 6))
    w = np.concatenate([rng.normal(0, 2000, (40, 3)), rng.normal(0, 200, (40, 3))], axis=1)
    return robot, q, w


def test_flips_are_the_simulated_labs_lost_motion_steps(setup):
    """A joint the planner counts travels its band in the lab (the output's offset from
    the motor side changes between the reference and the loaded state), and no other."""
    robot, q, w = setup
    lab = R.RealisticLab(lost_motion=BAND, gravity="flanks")
    w_ref = 0.1 * w
    step = (R.lost_motion_offset(robot, lab, q, w)
            - R.lost_motion_offset(robot, lab, q, w_ref))
    planned = flank_changes(robot, q, w, w_ref)
    assert np.array_equal(planned, step != 0)
    assert planned.sum() > 10  # the random loads do flip joints
    # by hand (Pinocchio's J, the gravity torques): sign of J^T w - g at each reading
    for p in range(5):
        g = gravity_torques(robot, q[p][None])[0]
        J = pin_jacobian(robot, q[p])
        assert np.array_equal(planned[p], np.sign(J.T @ w_ref[p] - g) != np.sign(J.T @ w[p] - g))


def test_unloaded_reference_flips_joint_1_under_a_lateral_load():
    """Axis 1 is vertical: no gravity torque, so the unloaded reference leaves it mid-band
    and any load with a torque about it moves it (issue 31)."""
    robot = load_robot("kr240-2")
    q = robot.from_controller(np.deg2rad([0.0, -90.0, 90.0, 0.0, 30.0, 0.0]))[None]
    w = np.array([[0.0, 2200.0, 0.0, 0.0, 0.0, 0.0]])
    assert flank_changes(robot, q, w, np.zeros((1, 6)))[0, 0]
    assert not flank_changes(robot, q, w, 0.05 * w)[0, 0]


def test_keeping_preload_is_the_threshold(setup):
    """Above the returned fraction no joint changes flank; just below it one does."""
    robot, q, w = setup
    f = keeping_preload(robot, q, w)
    assert np.all(np.isfinite(f)) and np.all((f >= 0) & (f < 1))
    above = (f * (1 + 1e-9) + 1e-12)[:, None] * w
    assert not flank_changes(robot, q, w, above).any()
    some = f > 1e-6
    below = (f * (1 - 1e-6))[:, None] * w
    assert np.all(flank_changes(robot, q[some], w[some], below[some]).any(axis=1))
