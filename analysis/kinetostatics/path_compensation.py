"""Deflection along a path and its compensation, with the refusals a robot program needs.

Batched over the points of the path: the predicted deflection at the
commanded joints (nonlinear equilibrium, with its covariance from the
identified compliances), the compensated joints
(:func:`analysis.kinetostatics.compensation.compensate`) and the uncertainty of
the error left after compensation. Points near a singularity or outside the
joint limits (before or after compensation) are refused with their CSV line.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from analysis.errors import InputError
from analysis.kinetostatics.compensation import Compensation, CompensationError, compensate
from analysis.kinetostatics.compensator_law import LawRangeError
from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.equilibrium import EquilibriumError
from analysis.kinetostatics.lost_motion import FlankOffsets, flank_offsets
from analysis.kinetostatics.uncertainty import DeflectionPrediction, predict_deflection
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

#: default smallest 1/kappa_F of the normalized Jacobian accepted on a path
MIN_INV_KAPPA = 0.02
#: largest pose residual of a compensated point accepted (m and rad): 1 um, 1 urad
MAX_RESIDUAL = 1e-6


@dataclass
class PathCompensation:
    """Result for a path of N points (SI, model convention, base frame).

    before : predicted deflection at the commanded joints (and its covariance);
    comp : compensated joints and their residual;
    after_cov (N, 6, 6) : covariance of the pose error left after compensation
        when the true compliances differ from the identified ones (propagated
        at the compensated joints);
    inv_kappa (N,) : 1/kappa_F of the normalized Jacobian at each point;
    length : the characteristic length used (m) and where it comes from;
    flanks : the lost-motion flank offsets subtracted from the compensated joints
        (:mod:`analysis.kinetostatics.lost_motion`; zeros without lost motion) and
        where they are unknown.
    """

    before: DeflectionPrediction
    comp: Compensation
    after_cov: np.ndarray
    inv_kappa: np.ndarray
    length: tuple[float, str]
    flanks: FlankOffsets | None = None


def _first(mask: np.ndarray, lines: np.ndarray, where: str) -> str:
    i = int(np.flatnonzero(mask)[0])
    extra = f" and {int(mask.sum()) - 1} more" if mask.sum() > 1 else ""
    return f"{where}:{int(lines[i])} (point {int(lines[i]) - 1}{extra})"


def _limits(robot: RobotModel, q: np.ndarray, lines, where: str, what: str) -> None:
    out = (q < robot.lower - 1e-12) | (q > robot.upper + 1e-12)
    if np.any(out):
        i, j = np.argwhere(out)[0]
        raise InputError(
            f"{what} q{j + 1} = {np.degrees(q[i, j]):.4f} deg is outside the joint limits "
            f"[{np.degrees(robot.lower[j]):g}, {np.degrees(robot.upper[j]):g}] deg (model "
            "convention)", where=_first(np.any(out, axis=1), lines, where))


def check_path(robot: RobotModel, q: np.ndarray, lines: np.ndarray, where: str,
               min_inv_kappa: float = MIN_INV_KAPPA) -> tuple[np.ndarray, tuple[float, str]]:
    """Refuse a path with a point outside the joint limits or near a singularity.

    q (N, n) commanded joints (rad); returns 1/kappa_F (N,) of the normalized
    Jacobian and the characteristic length used (m, where it comes from).
    """
    q = np.asarray(q, dtype=float)
    _limits(robot, q, lines, where, "commanded")
    if robot.characteristic_length is not None:
        length = (float(robot.characteristic_length), "robot model")
    else:
        length = (1.0, "1 m (the robot model has none)")
    inv_k = inverse_condition(normalized_jacobian(jacobian(robot, q), length[0]))
    near = inv_k < min_inv_kappa
    if np.any(near):
        i = int(np.flatnonzero(near)[0])
        raise InputError(f"near a singularity: 1/kappa_F = {inv_k[i]:.4f} < {min_inv_kappa:g} "
                         "(compensating there needs large joint corrections)",
                         where=_first(near, lines, where))
    return inv_k, length


def predict_path(robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray,
                 cov_x: np.ndarray | None, lines: np.ndarray,
                 where: str) -> DeflectionPrediction:
    """The predicted deflection at every point (see :func:`predict_deflection`); a point
    without equilibrium under its wrench is refused with its CSV line."""
    try:
        return predict_deflection(robot, q, k, w, cov_x)
    except EquilibriumError as err:
        bad = err.unconverged if err.unconverged is not None else np.ones(len(q), bool)
        raise InputError(f"no equilibrium under the wrench: {err}",
                         where=_first(bad, lines, where)) from None
    except LawRangeError as err:
        raise _law_range(err, lines, where) from None


def _law_range(err: LawRangeError, lines: np.ndarray, where: str) -> InputError:
    """The compensator law's refusal naming the CSV line (and the model file)."""
    return InputError(f"{err.message} ({err.where})", where=_first(err.bad, lines, where))


def compensate_path(robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray,
                    cov_x: np.ndarray | None, lines: np.ndarray, where: str,
                    min_inv_kappa: float = MIN_INV_KAPPA) -> PathCompensation:
    """Predict, compensate and check every point of a path (see module docstring).

    q (N, n) commanded joints (rad); k (n,) (N m/rad); w (N, 6) (N, N m);
    cov_x (n, n) covariance of the compliances or None; lines (N,) CSV lines
    and ``where`` (the file) for messages.
    """
    q = np.asarray(q, dtype=float)
    inv_k, length = check_path(robot, q, lines, where, min_inv_kappa)
    try:
        before = predict_deflection(robot, q, k, w, cov_x)
        comp = compensate(robot, q, k, w)
    except EquilibriumError as err:
        bad = err.unconverged if err.unconverged is not None else np.ones(len(q), bool)
        raise InputError(f"no equilibrium under the wrench: {err}",
                         where=_first(bad, lines, where)) from None
    except CompensationError as err:
        raise InputError(str(err), where=_first(err.failed, lines, where)) from None
    except LawRangeError as err:
        raise _law_range(err, lines, where) from None
    # lost motion (a model file's [model_class]): the output sits at the motor side plus
    # its flank offset, so the command is shifted back where the torque side is known
    flanks = flank_offsets(robot, comp.q_cmd, w)
    if np.any(flanks.offset):
        comp = replace(comp, q_cmd=comp.q_cmd - flanks.offset)
    _limits(robot, comp.q_cmd, lines, where, "compensated")
    res = np.maximum(np.linalg.norm(comp.residual[:, :3], axis=1),
                     np.linalg.norm(comp.residual[:, 3:], axis=1))
    if np.any(res > MAX_RESIDUAL):
        raise InputError("compensation residual above 1 um / 1 urad",
                         where=_first(res > MAX_RESIDUAL, lines, where))
    try:
        after = predict_deflection(robot, comp.q_cmd + flanks.offset, k, w, cov_x)
    except LawRangeError as err:  # the compensated q2 beyond the law's range
        raise _law_range(err, lines, where) from None
    return PathCompensation(before, comp, after.cov, inv_k, length, flanks)
