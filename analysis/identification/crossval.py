"""Validation by prediction on held-out poses (leave one pose out).

Each distinct pose in turn (tests at joint angles equal to within the encoder
noise, :mod:`analysis.identification.poses`, named by their labels) is removed,
the joint compliances are identified from the other tests with the same estimator, and the held-out
displacements are predicted (linear model for ols/wls, exact equilibrium for
exact). Reported per held-out pose: RMS prediction error of the translations
(m) and rotations (rad), and the RMS of the errors divided by the
measurement sigma (about 1 for a model that predicts to within the noise;
somewhat more because the estimate itself is uncertain).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.exact_fit import model_displacement
from analysis.identification.linear_model import design_block
from analysis.identification.measurements import TestArrays
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.poses import group_names, pose_groups, pose_tolerance
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
) -> pd.DataFrame | None:
    """Table of held-out prediction errors, or None with fewer than 3 distinct poses."""
    from analysis.identification.estimate import check_identifiable, check_tests, fit

    group = pose_groups(tests.q, pose_tolerance(noise))
    names = group_names(tests.pose, group)
    if len(names) < 3:
        return None
    rows = []
    for g, label in enumerate(names):
        held = group == g
        train, test = tests.subset(~held), tests.subset(held)
        row = {"held_out_pose": label, "n_tests": int(held.sum())}
        try:
            check_tests(robot, train, joints, noise)
            J = jacobian(robot, train.q)
            A = design_block(J, train.w)[..., list(joints)] * train.measured[..., None]
            check_identifiable(A, joints)
            x_p = fit(robot, train, joints, noise, method).x
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
