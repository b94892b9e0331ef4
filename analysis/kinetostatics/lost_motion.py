"""Lost motion in a compensated path: the flank offset of each gear where the side of its
torque is known.

A model file whose ``[model_class]`` carries ``lost_motion_rad`` (the dead band 2b_j of
each gear, rad, written by ``campaign analyze --model lost-motion``) says that the output
of joint j sits at the motor-side angle plus ``s_j = b_j sign(tau_j)``: half the band on
the side of the torque its gear carries (the simulated lab's and the analysis' one flank
rule, :func:`analysis.model.gravity.gear_flanks`). With the torque
``tau = J(q)^T w - g(q)`` (the robot file's mass model) the offset is known and the
command is shifted by ``-s`` so that the output lands where the compensation put it.
Where it is not known the offset is not applied and the point is named: a joint whose
torque is within :data:`~analysis.model.gravity.FLANK_TOLERANCE` of zero (its gear can
rest on either flank), or every joint with a band when the robot file has no mass model
(the weight's torque, usually the larger part, is unknown), or joint 2 when the model
carries an axis-2 compensator whose torque is not known (only its k2(q2) law). All SI.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.model.gravity import gear_flanks, gear_torques


@dataclass(frozen=True)
class FlankOffsets:
    """Per point and joint: ``offset`` (N, n) rad applied (0 where unknown), ``unknown``
    (N, n) bool (a band the torque side cannot place), ``why`` (one line, "" if none)."""

    offset: np.ndarray
    unknown: np.ndarray
    why: str


def lost_motion_of(robot) -> np.ndarray | None:
    """The dead bands 2b (n,) (rad) of a model file's ``[model_class]``, or None (none, or
    all zero)."""
    mc = getattr(robot, "model_class", None) or {}
    band = np.asarray(mc.get("lost_motion_rad") or (), dtype=float)
    return band if band.size and np.any(band > 0) else None


def flank_offsets(robot, q: np.ndarray, w: np.ndarray) -> FlankOffsets:
    """The flank offsets at the commanded joints q (N, n) (rad) under the wrenches w (N, 6)
    or (6,) (N, N m at P, base frame); zeros when the model has no lost motion."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    zeros = np.zeros(q.shape)
    band = lost_motion_of(robot)
    if band is None:
        return FlankOffsets(zeros, np.zeros(q.shape, bool), "")
    has = np.broadcast_to(band > 0, q.shape)
    if getattr(robot, "inertials", None) is None:
        return FlankOffsets(zeros, has.copy(), "the robot file has no mass model: the side "
                            "of each gear's torque (its weight's part) is unknown")
    side = gear_flanks(gear_torques(robot, q, w))
    unknown = has & (side == 0)
    why = ("a gear's torque within the flank tolerance of zero: it can rest on either "
           "flank" if np.any(unknown) else "")
    comp = (getattr(robot, "model_class", None) or {}).get("compensator")
    if comp and band.size > 1 and band[1] > 0:
        unknown[:, 1] = True  # its spring's torque is not in the model file
        side[:, 1] = 0.0
        why = ("joint 2's compensator torque is not known (the model file has its k2(q2) "
               "law only)" + ("; " + why if why else ""))
    return FlankOffsets(np.where(unknown, 0.0, 0.5 * band * side), unknown, why)
