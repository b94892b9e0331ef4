"""Feasibility and deflection of (placement, point, tool angle) triples, batched.

For every triple: inverse kinematics in one configuration, joint limits with a
margin, an optional keep-out box, then the deflection of P under the process
wrench. Two checks cost more than the rest together and are made only on the
path the angle selection picks (:func:`verify`): the forward kinematics of the
solution (1e-9 m, 1e-9 rad) and the distance to singularity (1/kappa_F of J_N,
a 6x6 inverse); a failing triple is struck out and the selection repeated.
The search model is the linear compliance without K_C,
``dX = J K_theta^-1 J^T w`` (eq. 12 of Dumas et al. 2011, inverted): it needs
no 6x6 solve per triple; the chosen placement is re-checked with the nonlinear
equilibrium (:mod:`analysis.kinetostatics.equilibrium`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.model.ik import FK_TOL, IKSolver, fit_limits, pose_error
from analysis.model.kinematics import chain_state, jacobian_from_state
from analysis.model.robot_model import RobotModel
from analysis.placement.poses import base_wrench, target_poses, tool_rotations

#: Reason codes of an infeasible triple, most basic first.
OK, UNREACHABLE, LIMITS, SINGULAR, KEEP_OUT = 0, 1, 2, 3, 4
REASONS = {UNREACHABLE: "unreachable (no inverse kinematics in this configuration)",
           LIMITS: "joint limits (with the margin)",
           SINGULAR: "too close to a singularity (1/kappa_F below the threshold)",
           KEEP_OUT: "a joint origin inside the keep-out box"}
#: Two-sided 95 % normal quantile: the upper bound is the upper end of the 95 % interval.
Z95 = 1.959963984540054
OBJECTIVES = ("max", "rms", "compliance")


@dataclass(frozen=True)
class Problem:
    """Everything a worker needs to evaluate placements (SI units, picklable).

    points (N, 3) m and axes (N, 3) of the path in the workpiece frame;
    wrench (N, 6) tool-frame wrench [N, N m] per point (None only for the
    compliance objective); angles (A,) free tool angles (rad); k (n,) joint
    stiffness (N m/rad); length: characteristic length L of J_N (m);
    min_inv_kappa: singularity threshold; margin: joint-limit margin (rad);
    max_step: largest joint motion between neighbouring points (rad);
    keep_out (3, 2) box in the base frame (m) or None; flags: configurations
    tried; cov_x (n, n) covariance of the compliances 1/k ((rad/(N m))^2) for the
    95 % upper bound, or None for the mean.
    """

    robot: RobotModel
    points: np.ndarray
    axes: np.ndarray
    wrench: np.ndarray | None
    angles: np.ndarray
    k: np.ndarray
    length: float
    min_inv_kappa: float
    margin: float
    max_step: float
    objective: str
    flags: tuple[tuple[int, int, int], ...]
    keep_out: np.ndarray | None = None
    cov_x: np.ndarray | None = None

    @property
    def rotations(self) -> np.ndarray:
        return tool_rotations(self.axes, self.angles)


@dataclass(frozen=True)
class Triples:
    """Result for a batch (P, N, A): reason code (0 = feasible), joints q (..., 6)
    (rad, fitted into the limits), cost (per-triple objective: |dp| (m) or the
    largest translational compliance (m/N); inf where infeasible), dp (..., 3)
    translational deflection (m, base frame)."""

    reason: np.ndarray
    q: np.ndarray
    cost: np.ndarray
    dp: np.ndarray


def evaluate(problem: Problem, solver: IKSolver, placements: np.ndarray,
             flags: tuple[int, int, int], rotations: np.ndarray | None = None,
             general: bool = False) -> Triples:
    """Evaluate every (placement, point, angle) triple in configuration ``flags``.

    A spherical wrist goes through :mod:`analysis.placement.wrist_eval` (J from the
    IK's frames) unless ``general``: then, as for every other solver, J comes from
    the chain kinematics of :mod:`analysis.model.kinematics` at the IK's joints.
    """
    robot = problem.robot
    R = problem.rotations if rotations is None else rotations
    if solver.kind == "spherical_wrist" and not general:
        from analysis.placement.wrist_eval import evaluate_wrist

        return Triples(*evaluate_wrist(problem, solver, np.asarray(placements, dtype=float),
                                       flags, R))
    T = target_poses(placements, problem.points, R)
    q, found = solver.solve(T, flags, check=False)
    q, in_limits = fit_limits(robot, np.where(found[..., None], q, 0.0), problem.margin)
    state = chain_state(robot, q)
    J = jacobian_from_state(state)
    reason = np.full(found.shape, OK, dtype=np.int8)
    if problem.keep_out is not None:
        o = state.origins
        box = problem.keep_out
        inside = np.all((o >= box[:, 0]) & (o <= box[:, 1]), axis=-1)
        reason[np.any(inside, axis=-1)] = KEEP_OUT
    reason[~in_limits] = LIMITS
    reason[~found] = UNREACHABLE
    # the tool-frame wrench in base axes: the target's rotation includes the yaw
    w = None if problem.wrench is None else base_wrench(T[..., :3, :3],
                                                        problem.wrench[:, None, :])
    dp, cost = costs(problem, J, w)
    cost = np.where(reason == OK, cost, np.inf)
    return Triples(reason, q, cost, dp)


def costs(problem: Problem, J: np.ndarray, w: np.ndarray | None):
    """(dp (..., 3) m, per-triple cost) of the linear compliance model without K_C.

    J (..., 6, n) at P; w (..., 6) base-frame wrench at P (N, N m) or None.
    """
    k = problem.k
    Jt = J[..., :3, :]
    if w is not None:
        tau = np.einsum("...ji,...j->...i", J, w)
        dq = tau / k
        dp = np.einsum("...ij,...j->...i", Jt, dq)
    else:
        dp = np.zeros(J.shape[:-2] + (3,))
    if problem.objective == "compliance":
        C = (Jt / k) @ np.swapaxes(Jt, -1, -2)
        return dp, np.linalg.eigvalsh(C)[..., -1]
    norm = np.linalg.norm(dp, axis=-1)
    if problem.cov_x is None:
        return dp, norm
    # dp is linear in the compliances x = 1/k: d dp / d x_j = J_t[:, j] tau_j (exact).
    S = Jt * tau[..., None, :]
    u = dp / np.where(norm > 0, norm, 1.0)[..., None]
    g = np.einsum("...i,...ij->...j", u, S)
    sd = np.sqrt(np.maximum(np.einsum("...i,ij,...j->...", g, problem.cov_x, g), 0.0))
    return dp, norm + Z95 * sd


def verify(problem: Problem, placements: np.ndarray, points: np.ndarray,
           rotations: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Reason codes (...) of the checks left out of :func:`evaluate`, at chosen triples.

    placements (..., 4), points (..., 3), rotations (..., 3, 3) workpiece frame,
    q (..., 6): FK must reach the target pose within FK_TOL, and 1/kappa_F of
    J_N must reach the threshold. Returns OK, UNREACHABLE or SINGULAR.
    """
    from analysis.placement.poses import placement_transforms

    Tp = placement_transforms(placements.reshape(-1, 4)).reshape(*placements.shape[:-1], 4, 4)
    T = np.zeros(Tp.shape)
    T[..., :3, :3] = Tp[..., :3, :3] @ rotations
    T[..., :3, 3] = np.einsum("...ij,...j->...i", Tp[..., :3, :3], points) + Tp[..., :3, 3]
    T[..., 3, 3] = 1.0
    state = chain_state(problem.robot, q)
    dpos, drot = pose_error(state.tip, T)
    inv_k = inverse_condition(normalized_jacobian(jacobian_from_state(state), problem.length))
    reason = np.full(dpos.shape, OK, dtype=np.int8)
    reason[inv_k < problem.min_inv_kappa] = SINGULAR
    reason[(dpos > FK_TOL) | (drot > FK_TOL)] = UNREACHABLE
    return reason
