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

from analysis.kinetostatics.equilibrium import EquilibriumError, newton_deflection
from analysis.kinetostatics.small_linalg import solve_dominant_columns
from analysis.kinetostatics.stiffness import complementary_stiffness_from_jacobian
from analysis.model.kinematics import chain_state, jacobian_from_state, pose_difference
from analysis.model.robot_model import RobotModel


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

    Raises
    ------
    EquilibriumError
        Newton's method did not converge for some pose.
    """
    dq, ok = solve_deflection_masked(robot, q, x, w, tol, max_iter)
    if not np.all(ok):
        raise EquilibriumError(
            f"equilibrium did not converge in {max_iter} Newton steps at "
            f"{int(np.sum(~ok))} pose(s): the wrench is too large for these compliances"
        )
    return dq


def solve_deflection_masked(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-15,
    max_iter: int = 50,
    max_deflection: float = 1.0,
    dq0: np.ndarray | None = None,
    keep: dict | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Like :func:`solve_deflection_compliance`, batched without raising.

    Returns dq (..., n) (rad, 0 where failed) and ``ok`` (...) bool: Newton
    converged (max |step| <= max(tol, 1e-12) at the end) with a finite
    deflection below ``max_deflection`` (rad) and a nonsingular Jacobian.
    Used where some of many campaigns may hold absurd estimates (Monte-Carlo).
    The solver is :func:`analysis.kinetostatics.equilibrium.newton_deflection`.

    ``dq0`` (..., n): a starting guess (the deflection at nearby compliances, or the
    first-order one); the same converged solution with fewer Newton steps. Poses
    where Newton from ``dq0`` fails are solved again from zero, so a guess never
    loses a solution the cold start finds.

    ``keep``: see :func:`newton_deflection` (left empty when some pose was solved again).
    """
    dq, bad, last = newton_deflection(robot, q, x, w, tol, max_iter, dq0=dq0,
                                      max_deflection=max_deflection, keep=keep)
    ok = ~bad & (last <= max(tol, 1e-12))
    if dq0 is not None and not np.all(ok):
        if keep is not None:
            keep.clear()
        n = q.shape[-1]
        retry = ~np.reshape(ok, -1)
        x = np.broadcast_to(np.asarray(x, dtype=float), q.shape)
        w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
        d2, b2, l2 = newton_deflection(robot, q.reshape(-1, n)[retry], x.reshape(-1, n)[retry],
                                       w.reshape(-1, 6)[retry], tol, max_iter,
                                       max_deflection=max_deflection)
        dq, ok = dq.reshape(-1, n).copy(), np.reshape(ok, -1).copy()
        dq[retry] = d2
        ok[retry] = ~b2 & (l2 <= max(tol, 1e-12))
        dq, ok = dq.reshape(q.shape), ok.reshape(q.shape[:-1])
    return dq, ok


def model_displacement(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True
) -> tuple[np.ndarray, np.ndarray | None]:
    """Exact displacement screw (..., 6) [m; rad] and its derivative (..., 6, n) w.r.t. x.

    The derivative has units m/(rad/(N m)) and rad/(rad/(N m)) and is exact
    (up to the Newton tolerance) at the solved equilibrium. Raises
    :class:`EquilibriumError` where the equilibrium cannot be solved.
    """
    screw, D, ok = model_displacement_masked(robot, q, x, w, with_jacobian)
    if not np.all(ok):
        raise EquilibriumError(
            f"equilibrium did not converge at {int(np.sum(~ok))} pose(s): the wrench is too "
            "large for these compliances"
        )
    return screw, D


def model_displacement_masked(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`model_displacement` plus ``ok`` (...) bool; values are 0 where not ok."""
    screw, D, ok, _ = model_displacement_state(robot, q, x, w, with_jacobian)
    return screw, D, ok


def model_displacement_state(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True,
    dq0: np.ndarray | None = None, unloaded: dict | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """:func:`model_displacement_masked` plus the joint deflection dq (..., n) (rad).

    Newton starts from ``dq0`` (e.g. the deflection of the previous Gauss-Newton
    iterate), else from the first-order deflection ``x * J(q)^T w`` (one Newton step
    fewer than from zero: the unloaded chain state is needed for the screw anyway).
    ``unloaded``: a dict that receives ``state`` and ``tip``, the chain state at q and
    its tool pose (a caller that also needs J(q) saves recomputing it); when it already
    holds ``tip`` (the same q) and ``dq0`` is given, the unloaded chain is not recomputed.
    """
    q = np.asarray(q, dtype=float)
    x = np.broadcast_to(np.asarray(x, dtype=float), q.shape)
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    if unloaded is not None and "tip" in unloaded and dq0 is not None:
        tip0 = unloaded["tip"]
    else:
        s0 = chain_state(robot, q)
        tip0 = s0.tip
        if unloaded is not None:
            unloaded.update(state=s0, tip=tip0)
        if dq0 is None:
            dq0 = x * np.einsum("...ji,...j->...i", jacobian_from_state(s0), w)
    keep: dict = {}
    dq, ok = solve_deflection_masked(robot, q, x, w, dq0=np.where(np.isfinite(dq0), dq0, 0.0),
                                     keep=keep)
    n = q.shape[-1]
    if keep:
        # Newton's last evaluated iterate: converged like dq (they differ by the last
        # step, <= 1e-15 rad), and its state, J and I - X K_C are already computed
        dq, s1, J1, M = keep["dq"], keep["state"], keep["J"], keep["dF"]
        dq = np.where(ok[..., None], dq, 0.0)
    else:
        s1 = chain_state(robot, q + dq)
        J1 = jacobian_from_state(s1)
        M = None
    screw = np.where(ok[..., None], pose_difference(tip0, s1.tip), 0.0)
    if not with_jacobian:
        return screw, None, ok, dq
    tau = np.einsum("...ji,...j->...i", J1, w)
    if M is None:
        M = np.eye(n) - x[..., :, None] * complementary_stiffness_from_jacobian(J1, w)
    M = np.where(ok[..., None, None], M, np.eye(n))
    # (..., n, n): d dq_i / d x_j; M = I - X K_C is diagonally dominant at ordinary loads
    ddq = solve_dominant_columns(M, tau[..., None, :] * np.eye(n))
    D = J1.copy()
    D[..., 3:, :] = so3_left_jacobian_inverse(screw[..., 3:]) @ J1[..., 3:, :]
    return screw, np.where(ok[..., None, None], D @ ddq, 0.0), ok, dq
