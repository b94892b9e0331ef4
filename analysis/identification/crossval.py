"""Validation by prediction on held-out poses (leave one pose out).

Each distinct pose label in turn is removed, the joint compliances are
identified from the other tests with the same estimator, and the held-out
displacements are predicted (linear model for ols/wls, exact equilibrium for
exact). Reported per held-out pose: RMS prediction error of the translations
(m) and rotations (rad), and the RMS of the errors divided by the
measurement sigma (about 1 for a model that predicts to within the noise;
somewhat more because the estimate itself is uncertain).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.exact_fit import model_displacement
from analysis.identification.linear_model import design_block
from analysis.identification.measurements import TestArrays
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def leave_one_pose_out(
    robot: RobotModel,
    tests: TestArrays,
    method: str,
    joints: tuple[int, ...],
    noise: NoiseModel,
    fit_training: Callable[[TestArrays], np.ndarray],
) -> pd.DataFrame | None:
    """Table of held-out prediction errors, or None with fewer than 3 distinct poses.

    ``fit_training(train)`` returns the compliances (p,) of ``joints`` identified
    from the training tests by the estimator being validated, or raises
    :class:`InputError` when they cannot be identified (the estimator is passed
    in, so that this module does not import the one that calls it).
    """
    labels = list(dict.fromkeys(tests.pose.tolist()))
    if len(labels) < 3:
        return None
    rows = []
    for label in labels:
        held = tests.pose == label
        train, test = tests.subset(~held), tests.subset(held)
        row = {"held_out_pose": label, "n_tests": int(held.sum())}
        try:
            x_p = fit_training(train)
        except InputError as err:
            rows.append({**row, "rms_translation_m": np.nan, "rms_rotation_rad": np.nan,
                         "rms_normalized": np.nan, "note": str(err)})
            continue
        x = np.zeros(6)
        x[list(joints)] = x_p
        if method == "exact":
            pred, _ = model_displacement(robot, test.q, x, test.w, with_jacobian=False)
        else:
            pred = np.einsum("mrj,j->mr", design_block(jacobian(robot, test.q), test.w), x)
        err = np.where(test.measured, test.d - pred, np.nan)
        Jt = jacobian(robot, test.q)
        C = np.einsum("...ij,j,...kj->...ik", Jt, x, Jt)
        sig = np.sqrt(np.diagonal(residual_covariance(noise, C), axis1=-2, axis2=-1))
        norm = err / sig
        rows.append({
            **row,
            "rms_translation_m": _rms(err[:, :3][test.measured[:, :3]]),
            "rms_rotation_rad": _rms(err[:, 3:][test.measured[:, 3:]]),
            "rms_normalized": _rms(norm[test.measured]),
            "note": "",
        })
    return pd.DataFrame(rows)
