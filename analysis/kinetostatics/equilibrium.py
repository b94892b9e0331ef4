"""The nonlinear elastostatic equilibrium and the finite displacement it produces.

``K_theta dq = J(q + dq)^T w`` is solved by Newton's method, batched over poses;
its Jacobian is ``K_theta - K_C(q + dq)``. This is the model the simulated lab
uses and the exact identification fits; the linear model of eq. 14 is its
first-order approximation.
"""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.stiffness import complementary_stiffness_from_state
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
    """
    q = np.asarray(q, dtype=float)
    k = np.asarray(k, dtype=float)
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    n = q.shape[-1]
    Kt = k[..., :, None] * np.eye(n)
    dq = np.zeros_like(q) if dq0 is None else np.array(dq0, dtype=float)
    for _ in range(max_iter):
        state = chain_state(robot, q + dq)
        J = jacobian_from_state(state)
        resid = k * dq - np.einsum("...ji,...j->...i", J, w)
        jac = Kt - complementary_stiffness_from_state(state, w)
        step = np.linalg.solve(jac, resid[..., None])[..., 0]
        dq = dq - step
        # relative to the deflection once it exceeds 1 rad: rounding keeps the step of a
        # converged large deflection above an absolute 1e-14 rad
        if np.max(np.abs(step), initial=0.0) <= tol * max(1.0, np.max(np.abs(dq), initial=0.0)):
            return dq
    raise EquilibriumError(
        f"equilibrium did not converge in {max_iter} Newton steps (last step "
        f"{np.max(np.abs(step)):.3g} rad): the wrench is too large for this stiffness",
        unconverged=np.max(np.abs(step), axis=-1) > tol,
    )


def displacement_screw(
    robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray
) -> np.ndarray:
    """Finite displacement of P under w: [p(q+dq) - p(q) (m); rotvec(R(q+dq) R(q)^T) (rad)]."""
    q = np.asarray(q, dtype=float)
    dq = solve_deflection(robot, q, k, w)
    t0 = chain_state(robot, q).tip
    t1 = chain_state(robot, q + dq).tip
    return pose_difference(t0, t1)
