"""Frame helpers: wrench transport to the base frame, and a least-squares rigid fit.

Pure numpy; lengths in m, forces in N, moments in N m.
"""

from __future__ import annotations

import numpy as np

from drivers.errors import DeviceFault


def _check_transform(T: np.ndarray, name: str) -> np.ndarray:
    T = np.asarray(T, dtype=float)
    if T.shape != (4, 4):
        raise ValueError(f"{name} must be a 4x4 homogeneous transform, got shape {T.shape}")
    R = T[:3, :3]
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
        raise ValueError(f"{name} rotation is not orthonormal and right-handed")
    return T


def wrench_to_base(
    wrench_sensor: np.ndarray,
    flange_pose: np.ndarray,
    sensor_mount: np.ndarray,
    tool_point: np.ndarray,
) -> np.ndarray:
    """Express a sensor-frame wrench in the base frame at the tool point.

    Parameters
    ----------
    wrench_sensor : array_like, shape (..., 6)
        [f (N), m (N m)] measured by the sensor, in the sensor frame at its origin.
    flange_pose : array_like, shape (4, 4)
        Pose of the flange in the base frame (m).
    sensor_mount : array_like, shape (4, 4)
        Pose of the sensor frame in the flange frame (m), from the protocol.
    tool_point : array_like, shape (3,)
        Tool point P in the base frame (m).

    Returns
    -------
    ndarray, shape (..., 6)
        [f (N), m (N m)] in the base frame, moment taken about P:
        ``f_b = R f_s``, ``m_P = R m_s + (o - P) x f_b`` where ``o`` is the
        sensor origin in the base frame.
    """
    w = np.asarray(wrench_sensor, dtype=float)
    if w.shape[-1] != 6:
        raise ValueError("wrench must have 6 components [fx fy fz mx my mz]")
    T = _check_transform(flange_pose, "flange_pose") @ _check_transform(
        sensor_mount, "sensor_mount")
    R, o = T[:3, :3], T[:3, 3]
    p = np.asarray(tool_point, dtype=float).reshape(3)
    f = w[..., :3] @ R.T
    m = w[..., 3:] @ R.T + np.cross(o - p, f)
    return np.concatenate([f, m], axis=-1)


def fit_rigid(model: np.ndarray, measured: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares rigid transform mapping model points onto measured points (Kabsch).

    Parameters
    ----------
    model : array_like, shape (k, 3)
        Reflector positions in the tool frame (m), k >= 3, not collinear.
    measured : array_like, shape (k, 3)
        The same reflectors measured in the tracker frame (m).

    Returns
    -------
    T : ndarray, shape (4, 4)
        Pose of the tool frame in the tracker frame: ``measured ~ R model + t``.
    rms : float
        Root-mean-square distance (m) between measured and fitted points.

    Raises
    ------
    DeviceFault
        If the reflectors are (nearly) collinear, so the rotation is undetermined.
    """
    A = np.asarray(model, dtype=float)
    B = np.asarray(measured, dtype=float)
    if A.shape != B.shape or A.ndim != 2 or A.shape[1] != 3 or A.shape[0] < 3:
        raise ValueError("need matching (k, 3) point sets with k >= 3")
    ca, cb = A.mean(axis=0), B.mean(axis=0)
    H = (A - ca).T @ (B - cb)
    U, S, Vt = np.linalg.svd(H)
    if S[1] < 1e-9 * max(S[0], 1e-30):
        raise DeviceFault("reflectors are collinear: the tool rotation cannot be computed")
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T)) or 1.0])
    R = Vt.T @ D @ U.T
    t = cb - R @ ca
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    resid = B - (A @ R.T + t)
    return T, float(np.sqrt(np.mean(np.sum(resid**2, axis=1))))


def rotvec_to_matrix(rv: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad), Rodrigues' formula."""
    rv = np.asarray(rv, dtype=float)
    th = float(np.linalg.norm(rv))
    if th < 1e-12:
        return np.eye(3)
    k = rv / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


def matrix_to_rotvec(R: np.ndarray) -> np.ndarray:
    """Rotation vector (rad) of a rotation matrix."""
    R = np.asarray(R, dtype=float)
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    th = np.arccos(c)
    if th < 1e-9:
        return np.zeros(3)
    if np.pi - th < 1e-6:
        w, V = np.linalg.eigh((R + R.T) / 2)
        axis = V[:, np.argmax(w)]
        return axis * th
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return v * th / (2 * np.sin(th))


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion [w, x, y, z] (normalised here)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def matrix_to_quat(R: np.ndarray) -> np.ndarray:
    """Unit quaternion [w, x, y, z] of a rotation matrix (w >= 0)."""
    rv = matrix_to_rotvec(R)
    th = np.linalg.norm(rv)
    if th < 1e-12:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[np.cos(th / 2)], np.sin(th / 2) * rv / th])


def pose_from_xyz_rotvec(v: np.ndarray) -> np.ndarray:
    """4x4 transform from [x, y, z (m), rx, ry, rz (rad rotation vector)] (UR convention)."""
    v = np.asarray(v, dtype=float)
    T = np.eye(4)
    T[:3, :3] = rotvec_to_matrix(v[3:6])
    T[:3, 3] = v[:3]
    return T
