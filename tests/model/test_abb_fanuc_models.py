"""The ABB IRB 6640 and FANUC R-2000iC models against the ROS-Industrial URDFs they come from.

The URDF joint chains are transcribed here as data (origin xyz in m, origin rpy in rad,
joint axis) from:

* ros-industrial/abb, abb_irb6640_support/urdf/irb6640_185_280_macro.xacro
* ros-industrial/fanuc, fanuc_r2000ic_support/urdf/r2000ic165f_macro.xacro

and composed with an independent forward kinematics (products of fixed transforms and
axis-angle rotations), then compared with the robot models' DH chains in the controller
convention: the URDFs' axes are the controllers' positive directions, and the FANUC
URDF's J3 is relative to link 2 (the ROS-Industrial FANUC driver adds J2 to the
controller's J3, J23_factor = 1).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot

HALF_PI = np.pi / 2

# (origin xyz, origin rpy, axis) of joint_1..joint_6, then the fixed joint to tool0
IRB6640_URDF = {
    "joints": [
        ((0, 0, 0.780), (0, 0, 0), (0, 0, 1)),
        ((0.320, 0, 0), (0, 0, 0), (0, 1, 0)),
        ((0, 0, 1.075), (0, 0, 0), (0, 1, 0)),
        ((0, 0, 0.2), (0, 0, 0), (1, 0, 0)),
        ((1.392, 0, 0), (0, 0, 0), (0, 1, 0)),
        ((0.2, 0, 0), (0, 0, 0), (1, 0, 0)),
    ],
    "tool0": ((0, 0, 0), (0, HALF_PI, 0)),
    "limits": [(-2.967, 2.967), (-1.134, 1.4855), (-3.142, 1.222), (-5.236, 5.236),
               (-2.094, 2.094), (-6.283, 6.283)],
}
R2000IC_URDF = {
    "joints": [
        ((0, 0, 0.670), (0, 0, 0), (0, 0, 1)),
        ((0.312, 0, 0), (0, 0, 0), (0, 1, 0)),
        ((0, 0, 1.075), (0, 0, 0), (0, -1, 0)),
        ((0, 0, 0.225), (0, 0, 0), (-1, 0, 0)),
        ((1.280, 0, 0), (0, 0, 0), (0, -1, 0)),
        ((0.215, 0, 0), (0, 0, 0), (-1, 0, 0)),
    ],
    "tool0": ((0, 0, 0), (np.pi, -HALF_PI, 0)),
    "limits_deg": [(-185, 185), (-60, 76), (-132, 180), (-360, 360), (-125, 125),
                   (-360, 360)],
}


def _transform(xyz, rpy) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # URDF rpy: fixed axes x, y, z
    T[:3, 3] = xyz
    return T


def urdf_tool0(urdf: dict, q: np.ndarray) -> np.ndarray:
    """Pose of tool0 in base_link for URDF joint values ``q`` (rad)."""
    T = np.eye(4)
    for (xyz, rpy, axis), angle in zip(urdf["joints"], q, strict=True):
        R = np.eye(4)
        R[:3, :3] = Rotation.from_rotvec(np.asarray(axis, float) * angle).as_matrix()
        T = T @ _transform(xyz, rpy) @ R
    return T @ _transform(*urdf["tool0"])


def fanuc_urdf_angles(q_ctrl: np.ndarray) -> np.ndarray:
    """FANUC controller angles -> URDF angles (ROS-Industrial: J3_urdf = J3 + J2)."""
    q = np.array(q_ctrl, dtype=float)
    q[..., 2] += q[..., 1]
    return q


@pytest.mark.parametrize("key, urdf, to_urdf", [
    ("irb6640", IRB6640_URDF, lambda q: q),
    ("r2000ic", R2000IC_URDF, fanuc_urdf_angles),
])
def test_flange_matches_urdf_tool0(key, urdf, to_urdf):
    robot = load_robot(key)
    rng = np.random.default_rng(7)
    q_model = rng.uniform(robot.lower, robot.upper, (200, 6))
    q_ctrl = robot.to_controller(q_model)
    ours = tool_pose(robot, q_model)
    for T, qc in zip(ours, q_ctrl, strict=True):
        ref = urdf_tool0(urdf, to_urdf(qc))
        np.testing.assert_allclose(T[:3, 3], ref[:3, 3], atol=1e-9)
        np.testing.assert_allclose(T[:3, :3], ref[:3, :3], atol=1e-9)
    # the zero position: wrist centre and flange ahead at known heights (m)
    home = tool_pose(robot, robot.from_controller(np.zeros(6)))[:3, 3]
    expect = {"irb6640": (0.320 + 1.392 + 0.200, 0, 0.780 + 1.075 + 0.200),
              "r2000ic": (0.312 + 1.280 + 0.215, 0, 0.670 + 1.075 + 0.225)}[key]
    np.testing.assert_allclose(home, expect, atol=1e-12)


def test_abb_limits_are_the_urdf_limits():
    robot = load_robot("irb6640")
    lim = np.array(IRB6640_URDF["limits"])
    # the URDF rounds to 1e-3 rad; its axis-2 upper limit 1.4855 rad is 85.11 deg, the
    # product specification's 85 deg is kept
    np.testing.assert_allclose(np.degrees(robot.lower), np.degrees(lim[:, 0]), atol=0.03)
    np.testing.assert_allclose(np.degrees(robot.upper), np.degrees(lim[:, 1]), atol=0.12)
    np.testing.assert_array_equal(robot.controller_matrix, np.eye(6))


def test_fanuc_coupling_both_ways():
    robot = load_robot("r2000ic")
    q_ctrl = np.radians([10.0, 30.0, -20.0, 40.0, 50.0, 60.0])
    q_model = robot.from_controller(q_ctrl)
    np.testing.assert_allclose(np.degrees(q_model), [10, 30, 10, 40, 50, -60], atol=1e-12)
    np.testing.assert_allclose(robot.to_controller(q_model), q_ctrl, atol=1e-15)
    # J2 alone keeps the controller's J3, i.e. the forearm's orientation (elevation)
    a = tool_pose(robot, robot.from_controller(np.radians([0, 0, 15, 0, 0, 0])))
    b = tool_pose(robot, robot.from_controller(np.radians([0, 40, 15, 0, 0, 0])))
    np.testing.assert_allclose(a[:3, :3], b[:3, :3], atol=1e-12)


def test_fanuc_model_box_inside_the_controller_j3_range():
    robot = load_robot("r2000ic")
    lim = np.radians(R2000IC_URDF["limits_deg"])
    corners = np.array([[0, q2, q3, 0, 0, 0] for q2 in (robot.lower[1], robot.upper[1])
                        for q3 in (robot.lower[2], robot.upper[2])])
    j3 = robot.to_controller(corners)[:, 2]
    assert np.all(j3 >= lim[2, 0] - 1e-12) and np.all(j3 <= lim[2, 1] + 1e-12)
    np.testing.assert_allclose([robot.lower[1], robot.upper[1]], lim[1], atol=1e-12)
    assert robot.nominal_stiffness is None
