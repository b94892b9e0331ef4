"""The exact (nonlinear) model of a stiffness test, written in joint compliances.

For joint compliances x (rad/(N m)), the joint deflection solves
``dq = x * J(q + dq)^T w`` (the equilibrium ``K_theta dq = J(q+dq)^T w`` with
K_theta = diag(1/x)); the measured displacement is the finite screw
``[p(q+dq) - p(q); rotvec(R(q+dq) R(q)^T)]``. Written in x, the model stays
defined for rigid joints (x = 0) and for the negative estimates noise can
produce, which the stiffness form cannot represent.

Its derivative with respect to x, used by Gauss-Newton:
``d(dq)/dx = (I - X K_C)^-1 diag(tau)``, tau = J(q+dq)^T w, K_C at q+dq
(eq. 8), and ``d(screw)/d(dq) = [J_v; J_l^-1(phi) J_w]`` at q+dq, where
J_l^-1 is the inverse left Jacobian of SO(3) at the rotation vector phi.
"""

from __future__ import annotations

import numpy as np

from analysis.equilibrium import EquilibriumError
from analysis.kinematics import chain_state, jacobian_from_state, pose_difference
from analysis.robot_model import RobotModel
from analysis.stiffness import complementary_stiffness_from_state


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(v.shape[:-1])
    return np.stack(
        [
            np.stack([z, -v[..., 2], v[..., 1]], -1),
            np.stack([v[..., 2], z, -v[..., 0]], -1),
            np.stack([-v[..., 1], v[..., 0], z], -1),
        ],
        -2,
    )


def so3_left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """J_l^-1(phi) (..., 3, 3) for rotation vectors phi (..., 3) (rad).

    ``d phi = J_l^-1(phi) omega`` for a small rotation omega applied on the
    left, exp(omega) exp(phi); series form below 1e-4 rad.
    """
    phi = np.asarray(phi, dtype=float)
    th = np.linalg.norm(phi, axis=-1)
    K = _skew(phi)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    coef = np.where(
        small,
        1.0 / 12.0 + th**2 / 720.0,
        1.0 / ths**2 - (1.0 + np.cos(ths)) / (2.0 * ths * np.sin(ths)),
    )
    return np.eye(3) - 0.5 * K + coef[..., None, None] * (K @ K)


def solve_deflection_compliance(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-15,
    max_iter: int = 50,
) -> np.ndarray:
    """dq (..., n) (rad) solving ``dq = x * J(q + dq)^T w`` by Newton's method.

    Parameters
    ----------
    q : (..., n) joint angles (rad). x : (n,) or (..., n) joint compliances
        (rad/(N m)), 0 for a rigid joint. w : (..., 6) wrench (N, N m).
    tol : convergence on max |step| (rad).
    """
    q = np.asarray(q, dtype=float)
    x = np.broadcast_to(np.asarray(x, dtype=float), q.shape)
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    n = q.shape[-1]
    dq = np.zeros_like(q)
    step = np.zeros_like(q)
    for _ in range(max_iter):
        state = chain_state(robot, q + dq)
        tau = np.einsum("...ji,...j->...i", jacobian_from_state(state), w)
        F = dq - x * tau
        dF = np.eye(n) - x[..., :, None] * complementary_stiffness_from_state(state, w)
        step = np.linalg.solve(dF, F[..., None])[..., 0]
        dq = dq - step
        if np.max(np.abs(step), initial=0.0) <= tol:
            return dq
    raise EquilibriumError(
        f"equilibrium did not converge in {max_iter} Newton steps (last step "
        f"{np.max(np.abs(step)):.3g} rad): the wrench is too large for these compliances"
    )


def model_displacement(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """Exact displacement screw (..., 6) [m; rad] and its derivative (..., 6, n) w.r.t. x.

    The derivative has units m/(rad/(N m)) and rad/(rad/(N m)) and is exact
    (up to the Newton tolerance) at the solved equilibrium.
    """
    q = np.asarray(q, dtype=float)
    x = np.broadcast_to(np.asarray(x, dtype=float), q.shape)
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    dq = solve_deflection_compliance(robot, q, x, w)
    s0 = chain_state(robot, q)
    s1 = chain_state(robot, q + dq)
    screw = pose_difference(s0.tip, s1.tip)
    if not with_jacobian:
        return screw, None
    J1 = jacobian_from_state(s1)
    tau = np.einsum("...ji,...j->...i", J1, w)
    n = q.shape[-1]
    M = np.eye(n) - x[..., :, None] * complementary_stiffness_from_state(s1, w)
    ddq = np.linalg.solve(M, tau[..., None, :] * np.eye(n))  # (..., n, n): d dq_i / d x_j
    D = J1.copy()
    D[..., 3:, :] = so3_left_jacobian_inverse(screw[..., 3:]) @ J1[..., 3:, :]
    return screw, D @ ddq
