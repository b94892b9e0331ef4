"""A URDF tool frame whose name is both a link and the fixed joint above it.

Many URDFs name a fixed joint after the link it carries (example-robot-data's
Unitree Z1: joint and link ``gripperStator``); Pinocchio then has a BODY and a
FIXED_JOINT frame of that name, and looking the name up without a type raised a
ValueError (a traceback from ``campaign robots z1.urdf --tip gripperStator``).
The link's frame is taken: it is where the joint puts the link, so both are the
same placement.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot

#: (parent, child, xyz m, axis) of the six revolute joints, base to flange
JOINTS = [
    ("base", "l1", (0, 0, 0.3), (0, 0, 1)),
    ("l1", "l2", (0, 0, 0.1), (0, 1, 0)),
    ("l2", "l3", (0.4, 0, 0), (0, 1, 0)),
    ("l3", "l4", (0.3, 0, 0.05), (1, 0, 0)),
    ("l4", "l5", (0.1, 0, 0), (0, 1, 0)),
    ("l5", "l6", (0.05, 0, 0), (1, 0, 0)),
]
TOOL_XYZ = (0.07, 0, 0)


def _urdf(shuffled: bool) -> str:
    links = ["base", *[c for _, c, _, _ in JOINTS], "tool"]
    joints = [
        f'<joint name="j{i + 1}" type="revolute"><parent link="{p}"/><child link="{c}"/>'
        f'<origin xyz="{" ".join(map(str, xyz))}" rpy="0 0 0"/>'
        f'<axis xyz="{" ".join(map(str, ax))}"/>'
        '<limit lower="-3" upper="3" effort="10" velocity="1"/></joint>'
        for i, (p, c, xyz, ax) in enumerate(JOINTS)
    ]
    # the fixed joint carries the name of its child link
    joints.append('<joint name="tool" type="fixed"><parent link="l6"/><child link="tool"/>'
                  f'<origin xyz="{" ".join(map(str, TOOL_XYZ))}" rpy="0 0 0"/></joint>')
    if shuffled:  # a file need not list the joints base to tip
        joints = joints[::-1]
    body = "".join(f'<link name="{n}"/>' for n in links) + "".join(joints)
    return f'<?xml version="1.0"?><robot name="shared_names">{body}</robot>'


@pytest.mark.parametrize("shuffled", [False, True])
def test_tip_named_like_its_fixed_joint_is_the_link(tmp_path, shuffled):
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf(shuffled))
    robot = load_robot(str(path), tip="tool")
    assert robot.n == 6
    # at q = 0 every rpy is 0: P is the sum of the offsets
    p0 = np.sum([xyz for _, _, xyz, _ in JOINTS], axis=0) + np.array(TOOL_XYZ)
    np.testing.assert_allclose(tool_pose(robot, np.zeros(6))[:3, 3], p0, atol=1e-12)
    # q1 = 90 deg (about z0) turns the whole arm: (x, y) -> (-y, x)
    q = np.zeros(6)
    q[0] = np.pi / 2
    np.testing.assert_allclose(tool_pose(robot, q)[:3, 3], [-p0[1], p0[0], p0[2]],
                               atol=1e-12)
    # q2 = 90 deg (about y1, at z = 0.4): the rest of the arm (+x) turns to -z
    q = np.zeros(6)
    q[1] = np.pi / 2
    reach = p0[0]
    np.testing.assert_allclose(tool_pose(robot, q)[:3, 3], [0.05, 0, 0.4 - reach],
                               atol=1e-12)


def test_tip_that_names_only_a_joint_still_found(tmp_path):
    """A revolute joint's name is a frame too (JOINT type): kept as before."""
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf(False))
    robot = load_robot(str(path), tip="j6")
    assert robot.n == 6
    p = np.sum([xyz for _, _, xyz, _ in JOINTS], axis=0)
    np.testing.assert_allclose(tool_pose(robot, np.zeros(6))[:3, 3], p, atol=1e-12)


def test_unknown_tip_is_one_line(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf(False))
    with pytest.raises(InputError, match="no frame named 'nope'"):
        load_robot(str(path), tip="nope")
