"""The joint path and deflections at one placement, from the search's choices.

Recomputes, for one placement, configuration and angle sequence: the joint
path (unwound so that joints turning more than a full turn move the short
way), the deflection of P under the wrench by the search model (linear, without
K_C) and by the nonlinear equilibrium with K_C
(:func:`analysis.kinetostatics.equilibrium.displacement_screw`) plus, for a model file
with link compliance, the links' sum_l J_l C_l J_l^T w
(:func:`analysis.kinetostatics.link_compliance.link_screw`, zeros without), 1/kappa_F.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError
from analysis.kinetostatics.compensator_law import pose_stiffness
from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.kinetostatics.link_compliance import link_screw
from analysis.model.ik import IKSolver, fit_limits
from analysis.model.kinematics import chain_state, jacobian_from_state
from analysis.placement.evaluate import Problem, costs
from analysis.placement.poses import base_wrench, target_poses


@dataclass(frozen=True)
class PathDetails:
    """The path at one placement (SI, base frame, model joint convention).

    q (N, n) rad; angle (N,) tool angle (rad); target (N, 4, 4) poses of P;
    reached (N, 3) P by forward kinematics (m); dp (N, 3) search-model deflection
    (m); dp_nonlinear (N, 3) nonlinear-equilibrium deflection (m) or None
    without a wrench; cost (N,) per-point cost; inv_kappa (N,); value: the
    objective recomputed from ``cost``.
    """

    q: np.ndarray
    angle: np.ndarray
    target: np.ndarray
    reached: np.ndarray
    dp: np.ndarray
    dp_nonlinear: np.ndarray | None
    cost: np.ndarray
    inv_kappa: np.ndarray
    value: float
    value_nonlinear: float | None


def _unwind(robot, q: np.ndarray) -> np.ndarray:
    """Joint path with neighbours joined the short way, moved by whole turns into the limits."""
    steps = np.pi - np.mod(np.pi - np.diff(q, axis=0), 2 * np.pi)
    path = q[0] + np.concatenate([np.zeros((1, q.shape[1])), np.cumsum(steps, axis=0)])
    out = path.copy()
    for j in range(q.shape[1]):
        fits = [path[:, j] + 2 * np.pi * k for k in (0, -1, 1, -2, 2)
                if np.all(path[:, j] + 2 * np.pi * k >= robot.lower[j])
                and np.all(path[:, j] + 2 * np.pi * k <= robot.upper[j])]
        if not fits:
            raise InputError(f"joint {j + 1} winds out of its limits along the path at this "
                             "placement (the path turns it by more than its range)",
                             where="--path")
        out[:, j] = fits[0]
    return out


def objective_value(cost: np.ndarray, objective: str) -> float:
    """The path objective from per-point costs: max, or root mean square for ``rms``."""
    if objective == "rms":
        return float(np.sqrt(np.mean(cost**2)))
    return float(np.max(cost))


def path_details(problem: Problem, placement: np.ndarray, flags: tuple[int, int, int],
                 angle_index: np.ndarray) -> PathDetails:
    """Recompute the path at ``placement`` (4,) with the chosen flags and angles (N,)."""
    robot = problem.robot
    N = problem.points.shape[0]
    R = problem.rotations[np.arange(N), angle_index]  # (N, 3, 3)
    T = target_poses(np.asarray(placement)[None], problem.points, R[:, None])[0, :, 0]
    q, ok = IKSolver.for_robot(robot).solve(T, flags)
    if not np.all(ok):
        raise InputError(f"no inverse kinematics at point {int(np.argmin(ok)) + 1} of the "
                         "chosen placement", where="--path")
    q, _ = fit_limits(robot, q, problem.margin)
    q = _unwind(robot, q)
    state = chain_state(robot, q)
    J = jacobian_from_state(state)
    inv_k = inverse_condition(normalized_jacobian(J, problem.length))
    w = None if problem.wrench is None else base_wrench(T[:, :3, :3], problem.wrench)
    dp, cost = costs(problem, J, w)
    dp_nl, value_nl = None, None
    if w is not None:
        # the re-check takes the model file's whole class: k2(q2) of an axis-2 compensator
        # law (problem.k itself without one) and the links' term
        k = pose_stiffness(robot, q, problem.k)
        dp_nl = (displacement_screw(robot, q, k, w) + link_screw(robot, q, w))[:, :3]
        if problem.objective != "compliance":
            value_nl = objective_value(np.linalg.norm(dp_nl, axis=1), problem.objective)
    return PathDetails(q, problem.angles[angle_index], T, state.tip[:, :3, 3], dp, dp_nl,
                       cost, inv_k, objective_value(cost, problem.objective), value_nl)
