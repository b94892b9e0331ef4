"""Deflection compensation: the joints to command so that the loaded tool reaches its target.

For commanded joints q (model convention) the unloaded pose of P is
``T(q)``. Under the process wrench w the robot settles at ``q_c + dq(q_c, w)``
where dq solves the equilibrium ``K_theta dq = J(q_c + dq)^T w``
(:func:`analysis.kinetostatics.equilibrium.solve_deflection`). The compensated
joints q_c solve ``T(q_c + dq(q_c, w)) = T(q)`` (6 equations, 6 unknowns), by
Newton's method batched over points. Its Jacobian follows from the implicit
function theorem: ``d(q_c + dq)/dq_c = (K_theta - K_C)^-1 K_theta`` (K_C at the
loaded configuration), so ``dT/dq_c = J (K_theta - K_C)^-1 K_theta`` and the
Newton step is ``K_theta^-1 (K_theta - K_C) J^-1 r`` for a pose residual r.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.kinetostatics.compensator_law import pose_stiffness
from analysis.kinetostatics.equilibrium import solve_deflection
from analysis.kinetostatics.link_compliance import link_screw
from analysis.kinetostatics.stiffness import complementary_stiffness_from_state
from analysis.model.kinematics import chain_state, jacobian_from_state, pose_difference, tool_pose
from analysis.model.robot_model import RobotModel

#: Newton stops when every point's pose residual is below this (m and rad).
TOLERANCE = 1e-11


class CompensationError(RuntimeError):
    """Newton's method on the compensated joints did not converge at some points.

    ``failed`` is the boolean mask over the batch of the points still off target.
    """

    def __init__(self, message: str, failed: np.ndarray) -> None:
        super().__init__(message)
        self.failed = failed


@dataclass(frozen=True)
class Compensation:
    """Compensated joints of a batch of points (SI, model convention).

    q_cmd (..., n) joints to command (rad); dq (..., n) joint deflection at
    q_cmd under the wrench (rad); residual (..., 6) loaded pose of P at q_cmd
    minus the target pose ``[dp (m); rotation vector (rad)]``; iterations:
    Newton steps taken.
    """

    q_cmd: np.ndarray
    dq: np.ndarray
    residual: np.ndarray
    iterations: int


def compensate(
    robot: RobotModel,
    q: np.ndarray,
    k: np.ndarray,
    w: np.ndarray,
    tol: float = TOLERANCE,
    max_iter: int = 20,
) -> Compensation:
    """Joints q_cmd with ``T(q_cmd + dq(q_cmd, w)) = T(q)`` for every point of the batch.

    q (..., n) target joints (rad); k (n,) joint stiffness (N m/rad); w (..., 6)
    wrench at P, base frame (N, N m). Raises :class:`CompensationError` naming
    the points that do not converge, and
    :class:`analysis.kinetostatics.equilibrium.EquilibriumError` when the
    equilibrium itself has no solution. A model file with the axis-2 compensator law
    has joint 2's stiffness k2(q2) at the commanded q2 of each step
    (:func:`~analysis.kinetostatics.compensator_law.pose_stiffness`, k the file's).
    """
    q = np.asarray(q, dtype=float)
    k0 = np.asarray(k, dtype=float)
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    target = tool_pose(robot, q)
    q_cmd = q.copy()
    dq = None
    for it in range(max_iter + 1):
        # the compensator law at the commanded joints (k0 itself without it); the Newton
        # step ignores k2's change with q_cmd (it converges, linearly in that part)
        k = pose_stiffness(robot, q_cmd, k0)
        dq = solve_deflection(robot, q_cmd, k, w, dq0=dq)
        loaded = chain_state(robot, q_cmd + dq)
        # a model file's link compliance moves P further by sum_l J_l C_l J_l^T w (the one
        # kernel, at the commanded joints; zeros without); the Newton step ignores its
        # small change with q_cmd (it converges, linearly in that part)
        resid = pose_difference(target, loaded.tip) + link_screw(robot, q_cmd, w)
        err = np.max(np.abs(resid), axis=-1)
        if np.all(err <= tol):
            return Compensation(q_cmd, dq, resid, it)
        if it == max_iter:
            break
        J = jacobian_from_state(loaded)
        M = k[..., :, None] * np.eye(q.shape[-1]) - complementary_stiffness_from_state(loaded, w)
        step = np.linalg.solve(J, resid[..., None])
        step = (M @ step)[..., 0] / k
        # points already on target keep their joints (no drift from round-off)
        q_cmd = q_cmd - np.where((err > tol)[..., None], step, 0.0)
    failed = err > tol
    raise CompensationError(
        f"compensation did not converge in {max_iter} Newton steps at {int(failed.sum())} "
        f"point(s) (largest residual {float(err.max()):.3g} m or rad)", failed)
