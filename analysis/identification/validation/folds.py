"""What every path of one leave-one-pose-out validation shares, as one record."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.model.robot_model import RobotModel


@dataclass(frozen=True)
class Folds:
    """The fit validated and its folds: the robot, the tests (SI), the estimator
    (``method``: ols, wls or exact), the 0-based joints and the noise model; ``group``
    (m,) the fold of each test and ``poses`` (m,) its pose group
    (:func:`~analysis.identification.poses.pose_groups`); ``names`` each fold's label;
    ``J`` the tests' Jacobians
    (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`; None: made
    where needed)."""

    robot: RobotModel
    tests: TestArrays
    method: str
    joints: tuple[int, ...]
    noise: NoiseModel
    group: np.ndarray
    poses: np.ndarray
    names: list
    J: object = None
