"""Geometry of one test: approach poses, displacement screws from tracker poses, wrenches.

Frames: the robot base frame F0 (model), the tracker frame, the tool frame
(reflectors and the tool point P), the force sensor frame. All SI (m, rad, N, N m).
"""

from __future__ import annotations

import numpy as np

from analysis.model.kinematics import jacobian, rotation_vector, tool_pose
from analysis.model.robot_model import RobotModel
from drivers.frames import rotvec_to_matrix, wrench_to_base

#: directions tried for the approach offset, base frame: up first, then sideways, down
APPROACH_DIRECTIONS = np.array([[0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0],
                                [0, 0, -1]], dtype=float)


def approach_pose(robot: RobotModel, q: np.ndarray, offset: float, margin: float) -> np.ndarray:
    """Joint angles (rad, model) of a pose ``offset`` metres from the tool point at ``q``.

    The tool point is moved along the first direction of
    :data:`APPROACH_DIRECTIONS` (base frame, orientation kept) whose pose
    stays inside the limits minus ``margin`` (rad), by Newton steps on the
    kinematics. Returns ``q`` itself when ``offset`` is 0.

    Raises
    ------
    ValueError
        If no direction gives a pose inside the limits.
    """
    q = np.asarray(q, dtype=float)
    if offset <= 0:
        return q.copy()
    target0 = tool_pose(robot, q)
    for direction in APPROACH_DIRECTIONS:
        qa = q.copy()
        goal = target0[:3, 3] + offset * direction
        for _ in range(20):
            T = tool_pose(robot, qa)
            err = np.concatenate([goal - T[:3, 3],
                                  rotation_vector(target0[:3, :3] @ T[:3, :3].T)])
            if np.linalg.norm(err[:3]) < 1e-7 and np.linalg.norm(err[3:]) < 1e-9:
                break
            qa = qa + np.linalg.lstsq(jacobian(robot, qa), err, rcond=None)[0]
        if np.all(np.isfinite(qa)) and bool(robot.within_limits(qa, margin)) and \
                np.max(np.abs(qa - q)) < np.deg2rad(30):
            return qa
    raise ValueError("no approach pose inside the joint limits minus the margin")


def base_in_tracker_rotation(tool_in_tracker: np.ndarray, tool_in_base: np.ndarray) -> np.ndarray:
    """Rotation (3, 3) of the base frame seen from the tracker, from one unloaded pose.

    ``R = R_tracker_tool R_base_tool^T``: the measured tool orientation against
    the orientation the robot model gives for the measured joint angles. Its
    error (model and tracker, about 1e-4 rad) rotates a millimetre displacement
    by well under a micrometre.
    """
    return np.asarray(tool_in_tracker)[:3, :3] @ np.asarray(tool_in_base)[:3, :3].T


def mean_pose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Mean of two nearby poses (4x4): mid-point and half-way rotation."""
    T = np.eye(4)
    T[:3, 3] = (a[:3, 3] + b[:3, 3]) / 2
    half = rotation_vector(b[:3, :3] @ a[:3, :3].T) / 2
    T[:3, :3] = rotvec_to_matrix(half) @ a[:3, :3]
    return T


def displacement(unloaded: np.ndarray, loaded: np.ndarray, r_base_in_tracker: np.ndarray
                 ) -> np.ndarray:
    """Displacement screw [dp (m); dr (rad)] of the tool, base-frame components.

    ``unloaded`` and ``loaded`` are tool poses in the tracker frame;
    ``dr = rotvec(R_loaded R_unloaded^T)`` as in :func:`analysis.model.kinematics.pose_difference`,
    both rotated from the tracker frame to the base frame.
    """
    R = np.asarray(r_base_in_tracker)
    dp = loaded[:3, 3] - unloaded[:3, 3]
    dr = rotation_vector(loaded[:3, :3] @ unloaded[:3, :3].T)
    return np.concatenate([R.T @ dp, R.T @ dr])


def loaded_tool_pose(tool_in_base: np.ndarray, screw: np.ndarray) -> np.ndarray:
    """Tool pose (base frame) displaced by ``screw`` [dp (m); dr (rad)]."""
    T = np.array(tool_in_base, dtype=float)
    T[:3, 3] = T[:3, 3] + screw[:3]
    T[:3, :3] = rotvec_to_matrix(screw[3:]) @ T[:3, :3]
    return T


def sensor_wrench_to_base(wrench: np.ndarray, tool_in_base: np.ndarray,
                          sensor_mount: np.ndarray) -> np.ndarray:
    """Sensor-frame wrench -> base-frame wrench at the tool point P (N, N m).

    ``sensor_mount`` is the sensor frame in the tool frame (4x4, m); P is the
    tool frame's origin.
    """
    T = np.asarray(tool_in_base, dtype=float)
    return wrench_to_base(wrench, T, sensor_mount, T[:3, 3])


def mount_matrix(xyz: np.ndarray | None, rpy: np.ndarray | None) -> np.ndarray:
    """4x4 sensor mount from a position (m) and roll-pitch-yaw angles (rad, x-y-z fixed axes)."""
    T = np.eye(4)
    if xyz is not None:
        T[:3, 3] = xyz
    if rpy is not None:
        r, p, y = rpy
        cx, sx, cy, sy, cz, sz = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
        Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
        Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
        Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
        T[:3, :3] = Rz @ Ry @ Rx
    return T
