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
  and its sign decides the gear flank the output rests on;
* :func:`gear_torque_sigmas` (robot, q, wrench sigma) -> the standard deviation of J^T w
  from the wrench noise, and :func:`flank_moments` (tau, sigma) -> the mean and variance
  of the flank when the torque is known to that noise only.

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


#: gear torques of magnitude up to this (N m) leave the output mid-band: the gravity torque
#: of a vertical axis is 0 to rounding (about 1e-12 of the arm's weight times its reach),
#: and its sign must not decide a flank
FLANK_TOLERANCE = 1e-6


def gear_flanks(tau: np.ndarray) -> np.ndarray:
    """The flank each gear rests on under the torques ``tau`` (N m, any shape): +1, -1,
    or 0 (mid-band, ``|tau| <=`` :data:`FLANK_TOLERANCE`). The one flank rule of the
    simulated lab, the planner and the analysis's lost-motion test."""
    tau = np.asarray(tau, dtype=float)
    return np.where(np.abs(tau) <= FLANK_TOLERANCE, 0.0, np.sign(tau))


#: a flank is decided (probability 1 to double precision) where the torque is at least this
#: many of its standard deviations from zero: beyond 8.4 sigma erf(z / sqrt 2) rounds to
#: exactly +-1 and the flank variance 4 Phi(z) Phi(-z) is below 4e-17 (at 5 sigma the
#: other flank still has a probability of 2.9e-7)
FLANK_DECIDED_SIGMAS = 8.5


def flank_moments(tau: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mean, variance) of the flank s (+1 or -1) a gear rests on when its torque is known
    as ``tau`` (N m) with a Gaussian standard deviation ``sigma`` (N m, same shape or
    broadcastable): with p = Phi(tau / sigma) the probability of the + flank, mean
    2p - 1 = erf(tau / (sigma sqrt 2)) and variance 4 p (1 - p).

    Where the flank is decided (``sigma`` 0, or ``|tau| >=`` :data:`FLANK_DECIDED_SIGMAS`
    sigma) the mean is :func:`gear_flanks` (mid-band 0 included) and the variance 0, bit for
    bit: a torque far from zero keeps the hard flank rule's numbers."""
    from scipy import special

    tau = np.asarray(tau, dtype=float)
    sigma = np.broadcast_to(np.asarray(sigma, dtype=float), tau.shape)
    hard = gear_flanks(tau)
    open_ = (sigma > 0) & (np.abs(tau) < FLANK_DECIDED_SIGMAS * sigma)
    z = np.where(open_, tau / np.where(open_, sigma, 1.0), 0.0)
    mean = np.where(open_, special.erf(z / np.sqrt(2.0)), hard)
    var = np.where(open_, 4.0 * special.ndtr(z) * special.ndtr(-z), 0.0)
    return mean, var


def gear_torque_sigmas(robot: RobotModel, q: np.ndarray,
                       wrench_sigma: np.ndarray) -> np.ndarray:
    """Standard deviation (N, n) (N m) of J(q)^T w at q (N, n) (rad) when the wrench's six
    components carry independent noise of standard deviations ``wrench_sigma`` ((N, 6) or
    (6,), N and N m, base frame at P): sqrt(sum_r J_rj^2 sigma_r^2). The mass model is
    taken as exact (its torque adds no variance)."""
    q = np.asarray(q, dtype=float)
    J = jacobian(robot, q)
    s = np.broadcast_to(np.asarray(wrench_sigma, dtype=float), (*q.shape[:-1], 6))
    return np.sqrt(np.einsum("...rj,...r->...j", J**2, s**2))


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
