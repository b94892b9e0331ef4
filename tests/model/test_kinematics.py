"""Forward kinematics and Jacobians: batched numpy vs Pinocchio vs finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.model.kinematics import (
    chain_state,
    jacobian,
    pin_jacobian,
    pin_tool_pose,
    pose_difference,
    tool_pose,
)
from analysis.model.robots import builtin_names, load_robot

ROBOTS = builtin_names()


def _random_q(robot, rng, size=None):
    lo = np.maximum(robot.lower, -np.pi)
    hi = np.minimum(robot.upper, np.pi)
    return rng.uniform(lo, hi, size=None if size is None else (size, robot.n))


def fd_jacobian(robot, q, h=1e-6):
    """Central differences of FK: translation and small rotation (rotation vector)."""
    J = np.zeros((6, robot.n))
    for i in range(robot.n):
        e = np.zeros(robot.n)
        e[i] = h
        J[:, i] = pose_difference(tool_pose(robot, q - e), tool_pose(robot, q + e)) / (2 * h)
    return J


def test_builtins_present():
    assert set(ROBOTS) == {"kr240-2", "fanuc-s420f", "puma560", "ur5e", "ur10e", "irb6640",
                           "r2000ic"}


@pytest.mark.parametrize("name", ROBOTS)
def test_jacobian_matches_finite_differences(name):
    robot = load_robot(name)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = _random_q(robot, rng)
        J = jacobian(robot, q)
        fd = fd_jacobian(robot, q)
        scale = np.abs(J).max()
        assert np.abs(J - fd).max() < 1e-7 * scale


@pytest.mark.parametrize("name", ROBOTS)
def test_batched_matches_pinocchio(name):
    robot = load_robot(name)
    rng = np.random.default_rng(11)
    qs = _random_q(robot, rng, 20)
    T = tool_pose(robot, qs)
    J = jacobian(robot, qs)
    for i, q in enumerate(qs):
        np.testing.assert_allclose(T[i], pin_tool_pose(robot, q), atol=1e-12)
        np.testing.assert_allclose(J[i], pin_jacobian(robot, q), atol=1e-12)


@pytest.mark.parametrize("name", [n for n in ROBOTS if load_robot(n).reference_poses])
def test_published_reference_poses(name):
    robot = load_robot(name)
    for ref in robot.reference_poses:
        np.testing.assert_allclose(tool_pose(robot, ref["q"])[:3, 3], ref["position"], atol=1e-6)


def test_reference_pose_is_checked_not_copied():
    """Changing one DH length moves the tool: the reference check can fail."""
    robot = load_robot("ur5e")
    p = tool_pose(robot, np.zeros(6))[:3, 3]
    assert p[0] == pytest.approx(-0.425 - 0.3922, abs=1e-12)
    assert p[1] == pytest.approx(-(0.1333 + 0.0996), abs=1e-12)


def test_kr240_geometry_modified_dh():
    """Modified DH (Table 1): theta2 = theta3 = 0 puts the upper arm horizontal and the
    forearm vertical; hand-computed wrist-centre and flange positions."""
    robot = load_robot("kr240-2")
    T = tool_pose(robot, np.zeros(6))
    # x = d2 + d3 + d4 (d4 = +0.041), z = RL4 + RL6
    np.testing.assert_allclose(T[:3, 3], [0.350 + 1.150 + 0.041, 0.0, 1.200 + 0.215], atol=1e-12)
    # home position A2 = -90, A3 = +90 (pendant) -> upper arm up, forearm forward
    q = robot.from_controller(np.radians([0, -90, 90, 0, 0, 0]))
    np.testing.assert_allclose(np.degrees(q[:3]), [0, 90, -180], atol=1e-12)
    # P = flange centre 1.109 m above A2 (1.150 - 0.041), 1.765 m ahead of A1
    np.testing.assert_allclose(tool_pose(robot, q)[:3, 3], [0.35 + 1.2 + 0.215, 0, 1.15 - 0.041],
                               atol=1e-12)


def test_kr240_forearm_axis_hangs_below_a3_at_home():
    """KUKA's KR 2000-family arms carry the A4 axis below A3 at the pendant home
    (0, -90, 90, 0, 0, 0): here 41 mm below, forearm along +x0, wrist axes on that line."""
    robot = load_robot("kr240-2")
    q = robot.from_controller(np.radians([0, -90, 90, 0, 0, 0]))
    s = chain_state(robot, q)
    a3, wrist = s.origins[2], s.origins[3]  # A4's frame origin is the wrist centre
    np.testing.assert_allclose(a3, [0.35, 0, 1.15], atol=1e-12)
    np.testing.assert_allclose(s.axes[3], [1, 0, 0], atol=1e-12)  # A4 along the forearm
    # the A4 axis (the line along x0 through the wrist centre) passes 41 mm below A3
    np.testing.assert_allclose(wrist - a3, [1.2, 0.0, -0.041], atol=1e-12)
    np.testing.assert_allclose(s.origins[4], wrist, atol=1e-12)  # A5 meets A4 there


def test_kr240_positive_pendant_directions_match_kuka():
    """Each A_i turns positive about KUKA's axis direction (base x forward, z up, home
    pose): A1 about -z, A2 and A3 about +y, A4 about -x, A5 about +y, A6 about -x. These
    are the joint axes of ROS-Industrial's sign-checked KUKA KR models (kuka_experimental:
    KR 150-2, KR 120 R2500 pro, KR 6/10/16 families)."""
    robot = load_robot("kr240-2")
    q0 = robot.from_controller(np.radians([0, -90, 90, 0, 0, 0]))
    s = chain_state(robot, q0)
    signed = s.axes * robot.controller_sign[:, None]
    kuka = np.array([[0, 0, -1], [0, 1, 0], [0, 1, 0], [-1, 0, 0], [0, 1, 0], [-1, 0, 0]])
    np.testing.assert_allclose(signed, kuka, atol=1e-12)
    # and independently of the axes: +10 deg on A5 from home tips the flange down (-z0)
    # as KUKA's A5 about +y does to a tool pointing along +x0
    q = robot.from_controller(np.radians([0, -90, 90, 0, 10, 0]))
    assert tool_pose(robot, q)[2, 3] < tool_pose(robot, q0)[2, 3] - 0.03


def test_puma_standard_dh_elbow_up_pose():
    """Standard DH hand computation: PUMA at q2 = 90 deg lifts the upper arm vertical."""
    robot = load_robot("puma560")
    q = np.radians([0, 90, 0, 0, 0, 0])
    p = tool_pose(robot, q)[:3, 3]
    # upper arm 0.4318 up, then a3 = 0.0203 up, forearm d4 = 0.4318 along -x, d3 offset -y
    np.testing.assert_allclose(p, [-0.4318, -0.15005, 0.4318 + 0.0203], atol=1e-12)


def test_controller_convention_round_trip():
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(3)
    q = _random_q(robot, rng, 10)
    np.testing.assert_allclose(robot.from_controller(robot.to_controller(q)), q, atol=1e-14)


def _erd_urdf(name):
    """A URDF shipped by the example-robot-data wheel (installed with the test extras)."""
    import sysconfig
    from pathlib import Path

    root = Path(sysconfig.get_paths()["purelib"]) / "cmeel.prefix/share/example-robot-data/robots"
    path = root / "ur_description/urdf" / name
    if not path.is_file():
        pytest.skip(f"example-robot-data URDF {name} not installed")
    return path


@pytest.mark.parametrize("urdf", ["ur5_robot.urdf", "ur5_gripper.urdf"])
def test_urdf_loaded_and_checked_against_finite_differences(urdf):
    robot = load_robot(str(_erd_urdf(urdf)), tip="tool0")
    assert robot.n == 6  # gripper joints, if any, are locked
    rng = np.random.default_rng(5)
    for _ in range(3):
        q = _random_q(robot, rng)
        J = jacobian(robot, q)
        np.testing.assert_allclose(J, pin_jacobian(robot, q), atol=1e-12)
        assert np.abs(J - fd_jacobian(robot, q)).max() < 1e-7


def test_urdf_matches_dh_model_of_same_robot():
    """The UR5 URDF and UR's DH table describe the same arm (UR5, not e-series:
    d1 = 0.089159, a2 = -0.425, a3 = -0.39225, d4 = 0.10915, d5 = 0.09465, d6 = 0.0823).
    The tool0 frame of the URDF sits at the DH flange; compare positions at random poses."""
    from analysis.model.dh import DHRow, build_dh_model
    from analysis.model.robot_model import RobotModel, chain_from_pinocchio

    urdf = load_robot(str(_erd_urdf("ur5_robot.urdf")), tip="tool0")
    rows = [DHRow(alpha=np.pi / 2, d=0.089159), DHRow(a=-0.425), DHRow(a=-0.39225),
            DHRow(alpha=np.pi / 2, d=0.10915), DHRow(alpha=-np.pi / 2, d=0.09465),
            DHRow(d=0.0823)]
    model, tip = build_dh_model(rows, "standard_dh")
    dh = RobotModel("ur5-dh", model, tip, urdf.lower, urdf.upper, chain_from_pinocchio(model, tip))
    rng = np.random.default_rng(9)
    for _ in range(5):
        q = _random_q(urdf, rng)
        p_urdf = tool_pose(urdf, q)[:3, 3]
        p_dh = tool_pose(dh, q)[:3, 3]
        # the URDF base_link is rotated 180 deg about z relative to UR's DH base
        np.testing.assert_allclose(p_urdf[:2], -p_dh[:2], atol=1e-6)
        assert p_urdf[2] == pytest.approx(p_dh[2], abs=1e-6)
