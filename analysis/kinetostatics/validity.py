"""Where the small-displacement (elastostatic) model stops describing a real arm.

The model of Dumas et al. 2011 treats each joint as a linear torsion spring and
the end-effector's displacement as a small screw (eq. 14 is its first-order
form). A deflection is refused as outside its validity when any of:

* a joint deflects by more than :data:`MAX_JOINT_ROTATION_RAD` (0.1 rad,
  5.7 deg): a real gearbox's torsion is a few mrad at its rated torque, and
  beyond this the linear spring is a guess;
* the rotation of the deflection screw exceeds :data:`MAX_SCREW_ROTATION_RAD`
  (0.1 rad): first-order (small-rotation) kinematics err by 1 - cos(0.1) = 0.5 %
  there, and the identification's linear model (eq. 14) by more;
* P moves by more than :data:`MAX_TRANSLATION_FRACTION` (5 %) of the arm's chain
  length (:attr:`analysis.model.robot_model.RobotModel.chain_length`).

Newton's non-convergence of the nonlinear equilibrium is refused separately
(:class:`analysis.kinetostatics.equilibrium.EquilibriumError`).
"""

from __future__ import annotations

import numpy as np

from analysis.errors import InputError
from analysis.model.robot_model import RobotModel

MAX_JOINT_ROTATION_RAD = 0.1
MAX_SCREW_ROTATION_RAD = 0.1
MAX_TRANSLATION_FRACTION = 0.05


def check_small_displacement(robot: RobotModel, dq: np.ndarray, screw: np.ndarray,
                             where: str = "--wrench") -> None:
    """Raise :class:`InputError` when the deflection is outside the model's validity.

    dq (n,) joint deflection (rad); screw (6,) [dp (m); rotation vector (rad)] of P
    under the load, from the nonlinear equilibrium. The message gives the
    criterion that failed and the likely causes.
    """
    dq, screw = np.asarray(dq, float), np.asarray(screw, float)
    j = int(np.argmax(np.abs(dq)))
    rot = float(np.linalg.norm(screw[3:]))
    dp = float(np.linalg.norm(screw[:3]))
    reach = robot.chain_length
    failed = []
    if abs(dq[j]) > MAX_JOINT_ROTATION_RAD:
        failed.append(f"joint {j + 1} deflects {1e3 * abs(dq[j]):.4g} mrad > "
                      f"{1e3 * MAX_JOINT_ROTATION_RAD:g} mrad")
    if rot > MAX_SCREW_ROTATION_RAD:
        failed.append(f"P rotates {1e3 * rot:.4g} mrad > {1e3 * MAX_SCREW_ROTATION_RAD:g} mrad")
    if dp > MAX_TRANSLATION_FRACTION * reach:
        failed.append(f"P moves {1e3 * dp:.4g} mm > {100 * MAX_TRANSLATION_FRACTION:g} % of "
                      f"the chain length {reach:.3g} m")
    if failed:
        raise InputError(
            "deflection outside the small-displacement model's validity ("
            + "; ".join(failed) + "): reduce the wrench, or check the joint stiffness "
            "(N m/rad) and the robot file's stiffness_unit and length_unit", where=where)
