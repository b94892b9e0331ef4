"""Inverse kinematics: round trips through forward kinematics for every built-in robot."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.model.ik import ALL_FLAGS, IKSolver, fit_limits, pose_error
from analysis.model.kinematics import tool_pose
from analysis.model.robots import builtin_names, load_robot, with_tool

EXPECTED_KIND = {"kr240-2": "spherical_wrist", "fanuc-s420f": "spherical_wrist",
                 "puma560": "spherical_wrist", "ur5e": "parallel_axes", "ur10e": "parallel_axes",
                 "irb6640": "spherical_wrist", "r2000ic": "spherical_wrist"}


def _angle_gap(a, b):
    return np.abs(np.pi - np.mod(np.pi - (a - b), 2 * np.pi))


@pytest.mark.parametrize("name", builtin_names())
def test_closed_form_round_trip(name):
    robot = load_robot(name)
    solver = IKSolver.for_robot(robot)
    assert solver.kind == EXPECTED_KIND[name]
    lo, hi = robot.map_limits()
    q = np.random.default_rng(1).uniform(lo, hi, size=(3000, 6))
    T = tool_pose(robot, q)
    recovered = np.zeros(len(q), dtype=bool)
    for flags in ALL_FLAGS:
        qs, ok = solver.solve(T, flags)
        # every accepted solution reaches the target to 1e-9 m and 1e-9 rad ...
        dp, dr = pose_error(tool_pose(robot, np.where(ok[:, None], qs, 0.0)), T)
        assert np.all(dp[ok] <= 1e-9) and np.all(dr[ok] <= 1e-9)
        assert np.all(np.isnan(qs[~ok]))
        recovered |= ok & np.all(_angle_gap(qs, q) < 1e-6, axis=1)
    # ... and one of the eight branches is the configuration the pose came from
    assert recovered.mean() > 0.999


def test_closed_form_with_a_tool_offset():
    robot = with_tool(load_robot("kr240-2"), np.array([0.05, -0.02, 0.3]),
                      np.radians([10.0, -20.0, 30.0]))
    solver = IKSolver.for_robot(robot)
    q = np.random.default_rng(2).uniform(*robot.map_limits(), size=(500, 6))
    T = tool_pose(robot, q)
    hits = np.zeros(len(q), dtype=bool)
    for flags in solver.flags:
        qs, ok = solver.solve(T, flags)
        hits |= ok & np.all(_angle_gap(qs, q) < 1e-6, axis=1)
    assert hits.all()


def test_branch_is_continuous_along_a_line():
    robot = load_robot("kr240-2")
    solver = IKSolver.for_robot(robot)
    T = np.repeat(tool_pose(robot, np.radians([10, 60, -120, 20, 50, 30]))[None], 200, axis=0)
    T[:, 0, 3] -= np.linspace(0, 0.3, 200)
    q, ok = solver.solve(T, (-1, 1, 1))
    assert ok.all()
    assert np.max(_angle_gap(q[1:], q[:-1])) < np.radians(2)


def test_numerical_solver_round_trip():
    robot = load_robot("puma560")
    solver = IKSolver(robot, "numerical")
    rng = np.random.default_rng(3)
    q = rng.uniform(*robot.map_limits(), size=(300, 6))
    qs, ok = solver.solve(tool_pose(robot, q), seed=q + rng.normal(0, 0.05, q.shape))
    assert ok.mean() > 0.99
    dp, dr = pose_error(tool_pose(robot, qs[ok]), tool_pose(robot, q[ok]))
    assert dp.max() <= 1e-9 and dr.max() <= 1e-9


def test_fit_limits_moves_by_whole_turns():
    robot = load_robot("kr240-2")  # theta3 in [-245, 30] deg
    q = np.radians([[0, 30, 160, 0, 0, 0], [0, 30, 100, 0, 0, 0]])
    fitted, ok = fit_limits(robot, q)
    assert ok.tolist() == [True, False]
    assert np.isclose(np.degrees(fitted[0, 2]), -200)
