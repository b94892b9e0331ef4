"""What the identified stiffness means at the tool: K_X at named poses, deflection maps.

Joints that were not identified are given the model's nominal stiffness
when known, else taken as rigid (:data:`~analysis.identification.prediction_stiffness.RIGID`);
:func:`~analysis.identification.prediction_stiffness.stiffness_for_prediction` says which.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.errors import InputError, SingularPoseError
from analysis.kinetostatics.maps import GridSpec, joint_space_map
from analysis.kinetostatics.stiffness import (
    cartesian_stiffness,
    complementary_stiffness,
    deflection,
)
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

MAP_POINTS = 61  # grid points along the longer of the theta_2, theta_3 ranges


@dataclass
class PoseStiffness:
    """K_X at one pose (SI blocks N/m, N/rad; N, N m/rad) and the deflection under w."""

    label: str
    q: np.ndarray
    K_X: np.ndarray
    K_X_no_KC: np.ndarray
    deflection: np.ndarray
    deflection_no_KC: np.ndarray


def pose_stiffness(robot: RobotModel, label: str, q: np.ndarray, k: np.ndarray,
                   w: np.ndarray) -> PoseStiffness:
    """K_X with K_C (eq. 6) and without (eq. 12) at q (rad) under w (N, N m)."""
    q = robot.check_q(np.asarray(q, dtype=float), where=f"pose {label}")
    J = jacobian(robot, q)
    K_C = complementary_stiffness(robot, q, w)
    try:
        K_X = cartesian_stiffness(J, k, K_C)
        K_0 = cartesian_stiffness(J, k)
    except SingularPoseError as err:
        raise InputError(f"J is singular at this pose: {err}", where=f"pose {label}") from err
    return PoseStiffness(label, q, K_X, K_0, deflection(J, k, w, K_C), deflection(J, k, w))


def map_grid(robot: RobotModel, fixed: np.ndarray, points: int = MAP_POINTS) -> GridSpec:
    """(theta_2, theta_3) grid over the joint limits (at most one turn), ``points`` per axis."""
    lo, hi = (v[1:3] for v in robot.map_limits())
    return GridSpec(np.linspace(lo[0], hi[0], points), np.linspace(lo[1], hi[1], points),
                    np.asarray(fixed, dtype=float))


def map_length(robot: RobotModel) -> tuple[float, str]:
    """Characteristic length L (m) for 1/kappa_F, and where it comes from."""
    if robot.characteristic_length:
        return float(robot.characteristic_length), "robot model"
    from analysis.kinetostatics.dexterity import characteristic_length

    return float(characteristic_length(robot, starts=2, samples=4000)[0]), \
        "computed (min kappa_F, Khan and Angeles)"


def deflection_map(robot: RobotModel, k: np.ndarray, w: np.ndarray, fixed: np.ndarray,
                   length: float, points: int = MAP_POINTS) -> pd.DataFrame:
    """Map table (:func:`analysis.kinetostatics.maps.joint_space_map`).

    Columns: 1/kappa_F, deflection_mm, x/y/z_m.
    """
    return joint_space_map(robot, map_grid(robot, fixed, points), k, w, length)


def load_cases(w: np.ndarray, force_sigma: float, moment_sigma: float,
               sigmas: float = 5.0) -> list[tuple[np.ndarray, int]]:
    """Distinct wrenches of measured tests, (mean wrench rounded to the noise, count).

    Tests whose wrenches agree within ``sigmas`` noise sigmas on every
    component are one load case (greedy, in test order). Of each case's mean,
    a component within 3 standard errors of zero is shown as 0 (a measured
    0.19 N of noise on a nominal zero is not a load) and the others are rounded
    to the decade below their standard error. Returns cases in order of first
    appearance.
    """
    w = np.asarray(w, dtype=float)
    scale = np.array([force_sigma] * 3 + [moment_sigma] * 3)
    label = np.full(len(w), -1)
    centres: list[np.ndarray] = []
    for i, wi in enumerate(w):
        for c, centre in enumerate(centres):
            if np.all(np.abs(wi - centre) <= sigmas * scale):
                label[i] = c
                break
        else:
            centres.append(wi)
            label[i] = len(centres) - 1
    out = []
    for c in range(len(centres)):
        n = int((label == c).sum())
        mean = w[label == c].mean(axis=0)
        se = scale / np.sqrt(n)
        step = 10.0 ** np.floor(np.log10(se))
        rounded = np.where(np.abs(mean) < 3 * se, 0.0, np.round(mean / step) * step)
        out.append((rounded + 0.0, n))
    return out
