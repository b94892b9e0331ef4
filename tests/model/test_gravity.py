"""Gravity torques of the mass model: against Pinocchio's computeGeneralizedGravity, a
finite difference of the potential energy, and a hand computation at the KUKA home pose."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest

from analysis.errors import InputError
from analysis.model.gravity import (
    STANDARD_GRAVITY,
    gear_torques,
    gravity_stiffness,
    gravity_torques,
    inertials_of,
)
from analysis.model.kinematics import pin_jacobian
from analysis.model.robots import load_robot


@pytest.fixture(scope="module")
def kr240():
    return load_robot("kr240-2")


def _poses(robot, count, seed=3):
    rng = np.random.default_rng(seed)
    lo, hi = np.maximum(robot.lower, -np.pi), np.minimum(robot.upper, np.pi)
    return rng.uniform(lo, hi, (count, robot.n))


def _massive_model(robot):
    """A copy of the robot's Pinocchio model with the file's masses (and some rotational
    inertia, which gravity must ignore) on its bodies, the tool on the last one."""
    model = robot.model.copy()
    inert = robot.inertials
    for i in range(robot.n):
        body = pin.Inertia(inert.masses[i], inert.coms[i], np.diag([1.0, 2.0, 3.0]))
        if i == robot.n - 1:
            body = body + pin.Inertia(inert.tool_mass, inert.tool_com, np.zeros((3, 3)))
        model.inertias[i + 1] = body
    model.gravity.linear = STANDARD_GRAVITY.copy()
    return model


def _potential(robot, model, q):
    """V(q) = -sum m g.c (J), the centres of mass placed by Pinocchio's kinematics."""
    data = model.createData()
    pin.forwardKinematics(model, data, q)
    return sum(-model.inertias[j].mass * STANDARD_GRAVITY
               @ data.oMi[j].act(model.inertias[j].lever) for j in range(1, model.njoints))


def test_matches_pinocchio_and_the_potential_energy(kr240):
    model = _massive_model(kr240)
    data = model.createData()
    q = _poses(kr240, 12)
    g = gravity_torques(kr240, q)
    h = 1e-6
    for p in range(len(q)):
        ref = pin.computeGeneralizedGravity(model, data, q[p])
        assert np.max(np.abs(g[p] - ref)) < 1e-9 * np.max(np.abs(ref))
        fd = np.array([(_potential(kr240, model, q[p] + h * e)
                        - _potential(kr240, model, q[p] - h * e)) / (2 * h)
                       for e in np.eye(kr240.n)])
        assert np.max(np.abs(g[p] - fd)) < 1e-5 * np.max(np.abs(ref))


def test_stiffness_is_the_derivative_of_the_torques(kr240):
    q = _poses(kr240, 6, seed=5)
    H = gravity_stiffness(kr240, q)
    h = 1e-6
    fd = np.stack([(gravity_torques(kr240, q + h * e) - gravity_torques(kr240, q - h * e))
                   / (2 * h) for e in np.eye(kr240.n)], axis=-1)
    assert np.max(np.abs(H - fd)) < 1e-5 * np.max(np.abs(H))
    assert np.allclose(H, np.swapaxes(H, -1, -2), rtol=0, atol=1e-9 * np.max(np.abs(H)))


def test_home_pose_by_hand(kr240):
    """A = 0, -90, 90, 0, 0, 0: upper arm vertical, forearm horizontal. Axes 2 and 3 hold
    the weight of everything beyond A3 at its horizontal distance from A3 (the 41 mm
    offset is vertical there): forearm centre 0.150 m, A4 tube 1.2 - 0.217, A5 1.2 + 0.044,
    flange 1.2 + 0.215 - 0.050, tool 1.2 + 0.215 + 0.100 m."""
    q = kr240.from_controller(np.deg2rad([0.0, -90.0, 90.0, 0.0, 0.0, 0.0]))
    moment = (182.0 * 0.150 + 44.5 * (1.2 - 0.217) + 18.5 * (1.2 + 0.044)
              + 1.6 * (1.2 + 0.215 - 0.050) + 50.0 * (1.2 + 0.215 + 0.100))
    g = gravity_torques(kr240, q[None])[0]
    expected = 9.80665 * moment
    # the sign is dV/dq's: V grows with q3 where g3 > 0 (checked on Pinocchio's kinematics)
    assert abs(abs(g[1]) - expected) < 1e-9 * expected
    assert abs(abs(g[2]) - expected) < 1e-9 * expected
    assert abs(g[0]) < 1e-9 and abs(g[3]) < 1e-9 and abs(g[5]) < 1e-9
    model = _massive_model(kr240)
    e3 = np.eye(kr240.n)[2] * 1e-6
    assert np.sign(_potential(kr240, model, q + e3) - _potential(kr240, model, q - e3)) \
        == np.sign(g[2])


def test_gear_torques_are_the_wrench_minus_gravity(kr240):
    q = _poses(kr240, 4, seed=9)
    w = np.array([2000.0, -1500.0, 800.0, 100.0, -50.0, 30.0])
    tau = gear_torques(kr240, q, w)
    for p in range(len(q)):
        ref = pin_jacobian(kr240, q[p]).T @ w - gravity_torques(kr240, q[p][None])[0]
        assert np.max(np.abs(tau[p] - ref)) < 1e-9 * np.max(np.abs(ref))


def test_no_mass_model_is_refused():
    robot = load_robot("irb6640")
    assert robot.inertials is None
    with pytest.raises(InputError, match="no mass model"):
        inertials_of(robot)
    with pytest.raises(InputError, match="no mass model"):
        gravity_torques(robot, np.zeros((1, 6)))


def test_tool_mass_counts(kr240):
    q = _poses(kr240, 3, seed=11)
    bare = dataclasses.replace(kr240, inertials=dataclasses.replace(kr240.inertials,
                                                                    tool_mass=0.0))
    model = _massive_model(bare)
    data = model.createData()
    for p in range(len(q)):
        ref = pin.computeGeneralizedGravity(model, data, q[p])
        assert np.max(np.abs(gravity_torques(bare, q[p][None])[0] - ref)) < 1e-9 * np.max(
            np.abs(ref))
    assert np.max(np.abs(gravity_torques(bare, q) - gravity_torques(kr240, q))) > 100.0
