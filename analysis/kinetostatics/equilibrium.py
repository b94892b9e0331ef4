"""The nonlinear elastostatic equilibrium and the finite displacement it produces.

``K_theta dq = J(q + dq)^T w`` is solved by Newton's method, batched over poses;
its Jacobian is ``K_theta - K_C(q + dq)``. This is the model the simulated lab
uses and the exact identification fits; the linear model of eq. 14 is its
first-order approximation.
"""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.small_linalg import solve_dominant, to_entry_major
from analysis.kinetostatics.stiffness import complementary_stiffness_from_jacobian
from analysis.model.kinematics import chain_state, jacobian_from_state, pose_difference
from analysis.model.robot_model import RobotModel


class EquilibriumError(RuntimeError):
    """Newton's method did not converge (load close to buckling the model).

    ``unconverged`` is a boolean mask over the batch (poses whose last step
    was still above the tolerance), or None.
    """

    def __init__(self, message: str, unconverged: np.ndarray | None = None) -> None:
        super().__init__(message)
        self.unconverged = unconverged


def newton_deflection(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-14,
    max_iter: int = 50,
    dq0: np.ndarray | None = None,
    max_deflection: float = np.inf,
    keep: dict | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The one Newton solver of the equilibrium, batched, in joint compliances; never raises.

    Solves ``F(dq) = dq - x * J(q + dq)^T w = 0`` (``K_theta dq = J^T w``
    multiplied by ``X = K_theta^-1``: the same Newton steps as the stiffness
    form, ``(K_theta - K_C)^-1 (K_theta dq - J^T w)``, and defined for rigid
    joints, x = 0). Its Jacobian is ``I - X K_C(q + dq)``.

    Parameters
    ----------
    q : (..., n) joint angles (rad). x : (n,) or (..., n) joint compliances
        (rad/(N m)). w : (..., 6) wrench [f (N); m (N m)] at P, base frame.
    tol : a pose has converged when its last max |step| <= tol (rad; relative to
        max |dq| when that exceeds 1 rad); iteration
        stops when every pose has converged or failed.
    dq0 : (..., n) starting guess (rad), zero if None.
    max_deflection : a pose whose |dq| exceeds this (rad) is marked failed.

    Returns
    -------
    dq : (..., n) deflection (rad), 0 where failed.
    failed : (...) bool, singular Newton matrix, non-finite or too large deflection.
    last_step : (...) last max |step| of each pose (rad), divided by max |dq| when that
        exceeds 1 rad; inf where failed.

    ``keep``: a dict to receive the last iterate the Newton matrix was evaluated at,
    ``dq`` (..., n), with its ``state`` (:class:`ChainState` at q + dq), ``J`` (..., 6, n)
    and ``dF`` (..., n, n) = I - X K_C there (I where failed). That iterate is as
    converged as the returned dq (they differ by the last step, at most ``tol``), and
    a caller that needs the state, J or K_C at the solution saves recomputing them.
    """
    q = np.asarray(q, dtype=float)
    x = np.broadcast_to(np.asarray(x, dtype=float), q.shape)
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    n = q.shape[-1]
    dq = np.zeros_like(q) if dq0 is None else np.array(dq0, dtype=float)
    bad = np.zeros(q.shape[:-1], dtype=bool)
    last = np.full(q.shape[:-1], np.inf)
    eye = np.eye(n)
    for _ in range(max_iter):
        state = chain_state(robot, q + dq)
        J = jacobian_from_state(state)
        tau = np.einsum("...ji,...j->...i", J, w)
        F = np.where(bad[..., None], 0.0, dq - x * tau)
        dF = eye - x[..., :, None] * complementary_stiffness_from_jacobian(J, w)
        bad |= ~np.isfinite(dF).all(axis=(-2, -1))
        dF = np.where(bad[..., None, None], eye, dF)
        bad |= _singular(dF)
        dF = np.where(bad[..., None, None], eye, dF)
        if keep is not None:
            keep.update(dq=dq, state=state, J=J, dF=dF)
        step = _solve(dF, F)
        dq = dq - step
        bad |= ~np.isfinite(dq).all(axis=-1) | (np.max(np.abs(dq), axis=-1) > max_deflection)
        dq = np.where(bad[..., None], 0.0, dq)
        # relative to the deflection once it exceeds 1 rad: rounding keeps the step of a
        # converged large deflection above an absolute 1e-14 rad
        scale = np.maximum(1.0, np.max(np.abs(dq), axis=-1, initial=0.0))
        last = np.where(bad, np.inf, np.max(np.abs(step), axis=-1, initial=0.0) / scale)
        if np.all(bad | (last <= tol)):
            break
    return dq, bad, last


def _singular(dF: np.ndarray) -> np.ndarray:
    """(...) bool: |det dF| < 1e-12 (the Newton matrix is singular to working precision).

    I - X K_C is strictly diagonally dominant at ordinary loads, and then
    |det| >= prod_i (|a_ii| - sum_j!=i |a_ij|) (Ostrowski): the determinant is computed
    only where that bound does not already exceed the threshold.
    """
    diag = np.abs(np.diagonal(dF, axis1=-2, axis2=-1))
    margin = 2.0 * diag - np.abs(dF).sum(axis=-1)
    check = ~(np.all(margin > 0, axis=-1) & (np.prod(np.maximum(margin, 0.0), axis=-1)
                                              >= 1e-12))
    out = np.zeros(dF.shape[:-2], dtype=bool)
    if np.any(check):
        out[check] = np.abs(np.linalg.det(dF[check])) < 1e-12
    return out


def _solve(dF: np.ndarray, F: np.ndarray) -> np.ndarray:
    """dF^-1 F for batches of n x n matrices (..., n, n) and vectors (..., n).

    Elimination over the whole batch at once where dF is diagonally dominant
    (:func:`analysis.kinetostatics.small_linalg.solve_dominant`; stable without
    pivoting), LAPACK with partial pivoting elsewhere.
    """
    n = dF.shape[-1]
    flat = dF.reshape(-1, n, n)
    if flat.shape[0] == 0:
        return np.zeros(F.shape)
    x = solve_dominant(to_entry_major(flat), np.ascontiguousarray(F.reshape(-1, n).T))
    return x.T.reshape(F.shape)


def solve_deflection(
    robot: RobotModel,
    q: np.ndarray,
    k: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-14,
    max_iter: int = 50,
    dq0: np.ndarray | None = None,
) -> np.ndarray:
    """Joint deflection dq (..., n) (rad) solving K_theta dq = J(q + dq)^T w.

    Parameters
    ----------
    q : (..., n) joint angles (rad); k : (n,) or (..., n) joint stiffness (N m/rad);
    w : (..., 6) wrench [f (N); m (N m)] at P, base frame.
    tol : convergence on max |step| (rad), relative to max |dq| when that exceeds 1 rad.
    dq0 : (..., n) starting guess (rad), e.g. the solution at a nearby pose; zero if None.

    Raises
    ------
    EquilibriumError
        Some pose did not converge in ``max_iter`` steps (or its Newton matrix
        is singular); ``unconverged`` masks those poses.
    """
    x = 1.0 / np.asarray(k, dtype=float)
    dq, bad, last = newton_deflection(robot, q, x, w, tol, max_iter, dq0)
    unconverged = bad | (last > tol)
    if np.any(unconverged):
        worst = np.max(np.where(np.isfinite(last), last, np.inf))
        raise EquilibriumError(
            f"equilibrium did not converge in {max_iter} Newton steps (last step "
            f"{worst:.3g} rad): the wrench is too large for this stiffness",
            unconverged=unconverged,
        )
    return dq


def displacement_screw(
    robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray
) -> np.ndarray:
    """Finite displacement of P under w: [p(q+dq) - p(q) (m); rotvec(R(q+dq) R(q)^T) (rad)]."""
    q = np.asarray(q, dtype=float)
    dq = solve_deflection(robot, q, k, w)
    t0 = chain_state(robot, q).tip
    t1 = chain_state(robot, q + dq).tip
    return pose_difference(t0, t1)
