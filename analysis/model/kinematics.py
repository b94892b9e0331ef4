"""Forward kinematics and the kinematic Jacobian of the tool point P.

Two implementations of the same quantities:

* batched numpy functions over the chain extracted from the Pinocchio model
  (:class:`analysis.model.robot_model.Chain`): a whole grid of poses at once;
* per-pose Pinocchio calls (``pin_*``), the reference the batched code is
  tested against.

Conventions: J is 6 x n, rows ``[linear; angular]``, maps joint rates (rad/s)
to the twist ``[dp/dt (m/s); omega (rad/s)]`` of P, base-frame axes
(Pinocchio's ``LOCAL_WORLD_ALIGNED`` at P).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from analysis.model.robot_model import RobotModel


def _rotations(axes: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation matrices (..., 3, 3) about unit ``axes`` (3,) by ``q`` (...)."""
    k = np.array(
        [[0.0, -axes[2], axes[1]], [axes[2], 0.0, -axes[0]], [-axes[1], axes[0], 0.0]]
    )
    s, c = np.sin(q)[..., None, None], np.cos(q)[..., None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


@dataclass(frozen=True)
class ChainState:
    """Kinematic state of a batch of poses (base frame, SI units).

    ``origins`` (..., n, 3) joint origins (m); ``axes`` (..., n, 3) joint axes;
    ``tip`` (..., 4, 4) pose of P.
    """

    origins: np.ndarray
    axes: np.ndarray
    tip: np.ndarray


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product over the last axis (faster than np.cross on large batches)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _rotate_frame(rot: np.ndarray, axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """rot @ R(axis, q) for batches: column operations when the axis is x, y or z."""
    for k in range(3):
        if axis[k] == 1.0 and np.count_nonzero(axis) == 1:
            i, j = (k + 1) % 3, (k + 2) % 3
            c, s = np.cos(q)[..., None], np.sin(q)[..., None]
            out = rot.copy()
            out[..., :, i] = c * rot[..., :, i] + s * rot[..., :, j]
            out[..., :, j] = -s * rot[..., :, i] + c * rot[..., :, j]
            return out
    return rot @ _rotations(axis, q)


def _compose(rot: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """rot (..., 3, 3) @ fixed (3, 3) as one matrix product over the whole batch."""
    return (rot.reshape(-1, 3) @ fixed).reshape(rot.shape)


def _apply(rot: np.ndarray, vec: np.ndarray) -> np.ndarray:
    """rot (..., 3, 3) @ vec (3,) as one matrix-vector product over the whole batch."""
    return (rot.reshape(-1, 3) @ vec).reshape(rot.shape[:-1])


def chain_state(robot: RobotModel, q: np.ndarray) -> ChainState:
    """Joint origins and axes and the tool pose, batched over the leading axes of q."""
    chain = robot.chain
    q = np.asarray(q, dtype=float)
    batch = q.shape[:-1]
    rot = np.broadcast_to(np.eye(3), (*batch, 3, 3)).copy()
    pos = np.zeros((*batch, 3))
    origins = np.empty((*batch, chain.n, 3))
    axes = np.empty((*batch, chain.n, 3))
    for i in range(chain.n):
        place = chain.placements[i]
        pos = pos + _apply(rot, place[:3, 3])
        rot = _compose(rot, place[:3, :3])
        origins[..., i, :] = pos
        axes[..., i, :] = _apply(rot, chain.axes[i])
        rot = _rotate_frame(rot, chain.axes[i], q[..., i])
    tip = np.zeros((*batch, 4, 4))
    tip[..., :3, :3] = _compose(rot, chain.tip[:3, :3])
    tip[..., :3, 3] = pos + _apply(rot, chain.tip[:3, 3])
    tip[..., 3, 3] = 1.0
    return ChainState(origins, axes, tip)


def tool_pose(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Homogeneous transform (..., 4, 4) of P in the base frame (m), batched."""
    return chain_state(robot, q).tip


def jacobian_from_state(state: ChainState) -> np.ndarray:
    """J (..., 6, n) from a :class:`ChainState`: column i = [w_i x (p - o_i); w_i]."""
    p = state.tip[..., None, :3, 3]
    lin = cross(state.axes, p - state.origins)
    return np.concatenate([np.swapaxes(lin, -1, -2), np.swapaxes(state.axes, -1, -2)], axis=-2)


def jacobian(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Kinematic Jacobian J (..., 6, n) of P, rows [linear; angular], base axes."""
    return jacobian_from_state(chain_state(robot, q))


def pin_tool_pose(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """Pose of P (4, 4) at one configuration, computed by Pinocchio."""
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, np.asarray(q, dtype=float))
    return data.oMf[robot.tip_frame].homogeneous.copy()


def pin_jacobian(robot: RobotModel, q: np.ndarray) -> np.ndarray:
    """J (6, n) at one configuration, computed by Pinocchio (LOCAL_WORLD_ALIGNED at P)."""
    data = robot.model.createData()
    q = np.asarray(q, dtype=float)
    pin.computeJointJacobians(robot.model, data, q)
    pin.updateFramePlacements(robot.model, data)
    return pin.getFrameJacobian(
        robot.model, data, robot.tip_frame, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    ).copy()


#: rotations of more than this angle (rad) go to Pinocchio's SO(3) logarithm, one at a time:
#: near pi the skew part of R no longer determines the axis accurately
LOG_NEAR_PI = 2.5


def rotation_vector(rot: np.ndarray) -> np.ndarray:
    """Rotation vector (..., 3) (rad) of rotation matrices (..., 3, 3).

    Batched SO(3) logarithm: with v the axial vector of (R - R^T)/2 (|v| = sin theta)
    and c = (tr R - 1)/2 = cos theta, theta = atan2(|v|, c) and the vector is
    v theta/|v| (1 when v = 0), accurate to rounding wherever theta is away from pi.
    Angles above :data:`LOG_NEAR_PI` go to Pinocchio's ``log3`` one matrix at a time
    (scipy's Rotation gives the same numbers, but importing scipy.spatial costs about
    0.35 s of CPU, paid by every command that reports a deflection).
    """
    rot = np.asarray(rot, dtype=float)
    v = 0.5 * np.stack([rot[..., 2, 1] - rot[..., 1, 2], rot[..., 0, 2] - rot[..., 2, 0],
                        rot[..., 1, 0] - rot[..., 0, 1]], axis=-1)
    s = np.sqrt(np.sum(v * v, axis=-1))
    c = 0.5 * (rot[..., 0, 0] + rot[..., 1, 1] + rot[..., 2, 2] - 1.0)
    theta = np.arctan2(s, c)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(s > 0, theta / np.where(s > 0, s, 1.0), 1.0)
    vec = v * ratio[..., None]
    far = ~(theta <= LOG_NEAR_PI)  # NaN input too: log3 decides
    if np.any(far):
        flat = rot.reshape(-1, 3, 3)
        out = vec.reshape(-1, 3)
        for i in np.flatnonzero(far.reshape(-1)):
            out[i] = pin.log3(flat[i])
        vec = out.reshape(vec.shape)
    return vec


def pose_difference(t_from: np.ndarray, t_to: np.ndarray) -> np.ndarray:
    """Displacement screw (..., 6) from pose ``t_from`` to ``t_to`` (4x4, base frame).

    ``[p_to - p_from (m); rotvec(R_to R_from^T) (rad)]``: the small rotation
    vector is expressed in the base frame, as the paper's delta_X.
    """
    dp = t_to[..., :3, 3] - t_from[..., :3, 3]
    dr = rotation_vector(t_to[..., :3, :3] @ np.swapaxes(t_from[..., :3, :3], -1, -2))
    return np.concatenate([dp, dr], axis=-1)
