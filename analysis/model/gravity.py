"""Gravity torques of an arm with a mass model, and the torque each gear transmits.

CONTRACT (issue 31; other modules and studies build on these names):

* :func:`inertials_of` (robot) -> :class:`~analysis.model.robot_model.Inertials`, or an
  :class:`~analysis.errors.InputError` "no mass model" when the robot file gives no link
  masses (``robot.inertials is None``: use that to test without raising);
* :func:`gravity_torques` (robot, q (N, n) rad) -> g(q) (N, n) N m: the generalised
  gravity, the torques the joints must supply to hold the arm still (Pinocchio's
  ``computeGeneralizedGravity`` convention, g = dV/dq with V the potential energy), tool
  mass included;
* :func:`gravity_stiffness` (robot, q) -> dg/dq (N, n, n) N m/rad (the Hessian of V);
* :func:`gear_torques` (robot, q, wrench (N, 6) or (6,)) -> J(q)^T w - g(q) (N, n) N m:
  the torque the load puts on each gear under an external wrench w (the project's wrench
  convention: [f (N); m (N m)] at the tool point P, base-frame components) and gravity.
  Positive: it turns the joint's output in +q; the elastic deflection is K^-1 times it,
  and its sign decides the gear flank the output rests on.

Gravity acts along -z of the base frame (:data:`STANDARD_GRAVITY`, 9.80665 m/s^2) unless a
``gravity`` vector (m/s^2, base frame) is given. Batched numpy; no Pinocchio call (the
tests cross-check against Pinocchio and a finite difference of the potential energy).
"""

from __future__ import annotations

import numpy as np

from analysis.errors import InputError
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import Inertials, RobotModel

#: gravity vector (m/s^2) in the base frame of a floor-mounted arm: standard gravity, -z
STANDARD_GRAVITY = np.array([0.0, 0.0, -9.80665])


def inertials_of(robot: RobotModel) -> Inertials:
    """The robot's mass model; a one-line error naming the fix when it has none."""
    if robot.inertials is None:
        raise InputError(f"no mass model for {robot.name}: its robot file gives no link "
                         "masses (joints[i].mass and com), which the gravity torques need",
                         where=robot.source_file or robot.name)
    return robot.inertials


def _rotation(axis: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Rotations (N, 3, 3) by angles q (N,) about the unit ``axis`` (3,) (Rodrigues)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]],
                  [-axis[1], axis[0], 0.0]])
    c, s = np.cos(q)[:, None, None], np.sin(q)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def body_frames(robot: RobotModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orientation (N, n, 3, 3) and origin (N, n, 3) (m) of each joint's body frame, base
    frame, for joint angles q (N, n) (rad, model convention)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    chain = robot.chain
    N, n = q.shape
    R = np.empty((N, n, 3, 3))
    o = np.empty((N, n, 3))
    r_prev = np.broadcast_to(np.eye(3), (N, 3, 3))
    o_prev = np.zeros((N, 3))
    for i in range(n):
        P = chain.placements[i]
        o_i = o_prev + r_prev @ P[:3, 3]
        r_i = r_prev @ P[:3, :3] @ _rotation(chain.axes[i], q[:, i])
        R[:, i], o[:, i] = r_i, o_i
        r_prev, o_prev = r_i, o_i
    return R, o


def _moments(robot: RobotModel, q: np.ndarray, gravity: np.ndarray | None):
    """z (N, n, 3) joint axes, S (N, n, 3) = sum over bodies b >= i of m_b (c_b - o_i)
    (kg m) and the gravity vector (3,)."""
    inert = inertials_of(robot)
    R, o = body_frames(robot, q)
    z = np.einsum("pijk,ik->pij", R, robot.chain.axes)
    c = o + np.einsum("pijk,ik->pij", R, inert.coms)  # (N, n, 3) centres of mass
    mc = inert.masses[None, :, None] * c
    mc[:, -1] += inert.tool_mass * (o[:, -1] + R[:, -1] @ inert.tool_com)
    m = inert.masses.copy()
    m[-1] += inert.tool_mass
    # suffix sums over the bodies distal to joint i (itself included)
    first = np.cumsum(mc[:, ::-1], axis=1)[:, ::-1]
    mass = np.cumsum(m[::-1])[::-1]
    S = first - mass[None, :, None] * o
    g = STANDARD_GRAVITY if gravity is None else np.asarray(gravity, dtype=float)
    return z, S, g


def gravity_torques(robot: RobotModel, q: np.ndarray,
                    gravity: np.ndarray | None = None) -> np.ndarray:
    """g(q) (N, n) (N m): the torques the joints must supply to hold the arm and its tool
    against gravity at joint angles q (N, n) (rad, model convention); g = dV/dq.

    dV/dq_i = -m g_vec . dc/dq_i summed over the bodies beyond joint i, with
    dc/dq_i = z_i x (c - o_i): g_i = -g_vec . (z_i x S_i).
    """
    q2 = np.atleast_2d(np.asarray(q, dtype=float))
    z, S, g = _moments(robot, q2, gravity)
    out = -np.einsum("k,pik->pi", g, np.cross(z, S))
    return out.reshape(np.shape(q))


def gravity_stiffness(robot: RobotModel, q: np.ndarray,
                      gravity: np.ndarray | None = None) -> np.ndarray:
    """dg/dq (N, n, n) (N m/rad), the Hessian of the potential energy at q (N, n) (rad).

    With v_i = z_i x S_i: dv_i/dq_j = z_j x v_i for j <= i (joint j turns everything
    beyond it) and z_i x (z_j x S_j) for j > i, so
    H[i, j] = -g_vec . (z_a x (z_b x S_b)), a = min(i, j), b = max(i, j).
    """
    q2 = np.atleast_2d(np.asarray(q, dtype=float))
    z, S, g = _moments(robot, q2, gravity)
    n = robot.n
    v = np.cross(z, S)  # (N, n, 3)
    H = np.empty((q2.shape[0], n, n))
    for b in range(n):
        for a in range(b + 1):
            h = -np.cross(z[:, a], v[:, b]) @ g
            H[:, a, b] = h
            H[:, b, a] = h
    return H.reshape(*np.shape(q)[:-1], n, n)


def gear_torques(robot: RobotModel, q: np.ndarray, wrench: np.ndarray,
                 gravity: np.ndarray | None = None) -> np.ndarray:
    """J(q)^T w - g(q) (N, n) (N m): the torque the external wrench w ((N, 6) or (6,),
    [f (N); m (N m)] at P, base frame) and gravity put on each gear at q (N, n) (rad).

    Positive turns the output in +q; its sign decides the gear flank. A robot without a
    mass model is refused (:func:`inertials_of`).
    """
    q = np.asarray(q, dtype=float)
    J = jacobian(robot, q)
    w = np.broadcast_to(np.asarray(wrench, dtype=float), (*q.shape[:-1], 6))
    return np.einsum("...ri,...r->...i", J, w) - gravity_torques(robot, q, gravity)
