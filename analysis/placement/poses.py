"""Tool frames along the path and placements of the workpiece in the robot base frame.

Conventions (SI):

* tool frame at a path point: z = the tool axis (from the tool into the part);
  x at angle 0 = the workpiece x axis made perpendicular to z (the y axis where
  the tool axis is within 25 deg of x); the free angle phi turns x and y about z.
* placement (x, y, z, yaw): the workpiece frame's origin is at (x, y, z) in the
  base frame and its axes are turned by yaw about the base z axis:
  ``p_base = (x, y, z) + Rz(yaw) p_part``.
"""

from __future__ import annotations

import numpy as np


def reference_frames(axes: np.ndarray) -> np.ndarray:
    """Tool rotations (N, 3, 3) at angle 0 in the workpiece frame for unit axes (N, 3)."""
    ex = np.array([1.0, 0.0, 0.0])
    ey = np.array([0.0, 1.0, 0.0])
    near_x = np.abs(axes @ ex) > np.cos(np.radians(25.0))
    e = np.where(near_x[:, None], ey, ex)
    x = e - np.sum(e * axes, axis=1, keepdims=True) * axes
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    y = np.cross(axes, x)
    return np.stack([x, y, axes], axis=-1)


def tool_rotations(axes: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """Tool rotations (N, A, 3, 3) in the workpiece frame for axes (N, 3) and angles (A,) rad."""
    ref = reference_frames(axes)
    c, s = np.cos(angles), np.sin(angles)
    rz = np.zeros((angles.size, 3, 3))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1], rz[:, 2, 2] = c, -s, s, c, 1.0
    return ref[:, None] @ rz[None]


def placement_transforms(placements: np.ndarray) -> np.ndarray:
    """Homogeneous transforms (P, 4, 4) of placements (P, 4) = (x, y, z (m), yaw (rad))."""
    placements = np.atleast_2d(placements)
    T = np.zeros((placements.shape[0], 4, 4))
    c, s = np.cos(placements[:, 3]), np.sin(placements[:, 3])
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 2, 2] = T[:, 3, 3] = 1.0
    T[:, :3, 3] = placements[:, :3]
    return T


def target_poses(placements: np.ndarray, points: np.ndarray, rotations: np.ndarray) -> np.ndarray:
    """Poses of P (P, N, A, 4, 4) in the base frame.

    placements (P, 4); points (N, 3) m and rotations (N, A, 3, 3), workpiece frame.
    """
    Tp = placement_transforms(placements)
    R = Tp[:, None, None, :3, :3] @ rotations[None]
    p = np.einsum("kij,nj->kni", Tp[:, :3, :3], points) + Tp[:, None, :3, 3]
    out = np.zeros((*R.shape[:3], 4, 4))
    out[..., :3, :3] = R
    out[..., :3, 3] = p[:, :, None, :]
    out[..., 3, 3] = 1.0
    return out


def base_wrench(rotations: np.ndarray, wrench_tool: np.ndarray) -> np.ndarray:
    """Wrench at P in base-frame components (..., 6) from tool-frame components (..., 6)."""
    f = np.einsum("...ij,...j->...i", rotations, wrench_tool[..., :3])
    m = np.einsum("...ij,...j->...i", rotations, wrench_tool[..., 3:])
    return np.concatenate([f, m], axis=-1)
