"""The identification problem as one object: robot, tests, noise model, joints, options.

:class:`IdentificationProblem` is what every stage of
:func:`analysis.identification.estimate.identify` receives instead of loose parameters.
What the stages of one identification share is made once and kept on it: the tests'
Jacobians J (m, 6, 6), their design A (m, 6, p) (let go after the linear fits), the pose
groups and the validation's folds. Nothing is kept between identifications: the
object, and with it J, goes when the identification returns.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from analysis.errors import InputError
from analysis.identification.checks.data import COND_LIMIT
from analysis.identification.estimators.irls import ROBUST_METHODS
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.model.robot_model import RobotModel

METHODS = ("ols", "wls", "exact")
DEFAULT_METHOD = "exact"
COVARIANCES = ("model", "residual")
#: family-wise level of the outlier test: the chance that any residual of a fit to data
#: that follow the noise model is flagged
OUTLIER_FAMILY_LEVEL = 0.01


def referenced(tests: TestArrays, method: str) -> TestArrays:
    """Tests whose reference readings were taken under a preload (``tests.w_ref``; their
    ``w`` is the wrench difference): the linear model is ``J K^-1 J^T w``, the exact one
    the displacement between the equilibria under w_ref and w + w_ref. A campaign too
    large to hold its systems (streamed fits) is refused with a preload: its per-block
    model does not take the reference equilibria."""
    from analysis.identification.streaming.per_test import streamed

    if tests.w_ref is not None and method == "exact" and streamed(tests.m, ()):
        raise InputError(f"{tests.m} tests with reference readings under a preload: the "
                         "exact model of the two equilibria is not streamed; use --method "
                         "wls or fewer tests", where="--method")
    return tests


@dataclass(frozen=True)
class IdentifyOptions:
    """How to identify (see :func:`analysis.identification.estimate.identify`).

    method: "ols", "wls" or "exact"; robust: "none", "huber" or "tukey" (IRLS around
    ``method``); covariance: "model" (the noise model's sigmas taken as known) or
    "residual" (scaled by the reduced chi-square); cond_limit: the largest condition
    number of the column-scaled design; outlier_level: family-wise level of the outlier
    test; validate: leave-one-pose-out validation; confidence: of the intervals;
    holdout_radius: poses closer than this (rad, ||dq|| over the joints) are held out
    together (None: :data:`analysis.identification.validation.holdout_check.CLUSTER_DEG`).
    """

    method: str = DEFAULT_METHOD
    covariance: str = "model"
    cond_limit: float = COND_LIMIT
    outlier_level: float = OUTLIER_FAMILY_LEVEL
    validate: bool = True
    confidence: float = 0.95
    robust: str = "none"
    holdout_radius: float | None = None

    def check(self) -> None:
        """Refuse an unknown method, covariance or robust mode, or robust OLS."""
        if self.method not in METHODS:
            raise InputError(f"unknown method {self.method!r}: expected one of "
                             f"{', '.join(METHODS)}", where="--method")
        if self.covariance not in COVARIANCES:
            raise InputError(f"expected 'model' or 'residual', got {self.covariance!r}",
                             where="covariance")
        if self.robust not in ROBUST_METHODS:
            raise InputError(f"unknown robust estimator {self.robust!r}: expected one of "
                             f"{', '.join(ROBUST_METHODS)}", where="--robust")

    @property
    def radius(self) -> float:
        """The held-out radius (rad)."""
        if self.holdout_radius is not None:
            return self.holdout_radius
        from analysis.identification.validation.holdout_check import CLUSTER_DEG

        return float(np.radians(CLUSTER_DEG))


@dataclass(frozen=True, eq=False)
class IdentificationProblem:
    """Robot (6 joints), tests (SI), noise model, 0-based joints identified, options.

    Make it with :meth:`make` (checks the options and the joints). The cached
    attributes are made on first use and live as long as the object.
    """

    robot: RobotModel
    tests: TestArrays
    noise: NoiseModel
    joints: tuple[int, ...]
    options: IdentifyOptions
    #: the tests' reference readings were under a preload: ``tests.w`` is the wrench
    #: difference w - w_ref (:func:`referenced`)
    preloaded: bool = False

    @classmethod
    def make(cls, robot: RobotModel, tests: TestArrays, joints=None,
             noise: NoiseModel | None = None,
             options: IdentifyOptions | None = None) -> IdentificationProblem:
        """The problem with its defaults filled in: all six joints, or (0, 1, 2) when no
        rotation is measured; :class:`NoiseModel()`; :class:`IdentifyOptions()`."""
        options = options or IdentifyOptions()
        options.check()
        noise = noise or NoiseModel()
        if joints is None:
            joints = tuple(range(6)) if tests.has_rotations else (0, 1, 2)
        joints = tuple(sorted({int(j) for j in joints}))
        if not joints or joints[0] < 0 or joints[-1] > 5:
            raise InputError(f"expected 0-based joint indices 0..5, got {joints}",
                             where="joints")
        return cls(robot, referenced(tests, options.method), noise, joints, options,
                   tests.w_ref is not None)

    @property
    def p(self) -> int:
        """Number of compliances identified."""
        return len(self.joints)

    @property
    def systems(self):
        """The :class:`~analysis.identification.streaming.systems.LinearisedSystems` of this
        campaign's fits (:func:`~analysis.identification.streaming.systems.systems_for`):
        what the estimators do differently at its size, without asking for the size."""
        from analysis.identification.streaming.systems import systems_for

        return systems_for(self.tests.m)

    @property
    def large(self) -> bool:
        """The fits stream over per-test blocks made when sliced (more than
        :data:`~analysis.identification.streaming.per_test.LAZY_TESTS` tests); the
        identification's stages use it to give freed memory back between them."""
        return self.systems.streamed

    @cached_property
    def pose_group(self) -> np.ndarray:
        """(m,) pose index of each test (:func:`~analysis.identification.poses.pose_groups`;
        1-2 s at 1e6 tests: made once)."""
        from analysis.identification.poses import pose_groups, pose_tolerance

        return pose_groups(self.tests.q, pose_tolerance(self.noise))

    @cached_property
    def folds(self) -> np.ndarray:
        """(m,) the validation's fold of each test: the poses, those within the held-out
        radius of each other together (the poses when not validating)."""
        if not self.options.validate:
            return self.pose_group
        from analysis.identification.validation.holdout_check import holdout_folds

        return holdout_folds(self.tests.q, self.pose_group, self.options.radius)

    @cached_property
    def jacobian(self):
        """J (m, 6, 6) of the tests' joint angles
        (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`)."""
        from analysis.identification.estimators.linear_model import jacobian_blocks

        return jacobian_blocks(self.robot, self.tests.q)

    @cached_property
    def design(self):
        """(J, A): J and the linear model's design (m, 6, p) of the joints, zero rows where
        not measured; :meth:`release_design` lets A go (~0.3 GB at 1e6 tests)."""
        from analysis.identification.estimators.linear_model import tests_design

        return tests_design(self.robot, self.tests, self.joints, self.jacobian)

    def release_design(self) -> None:
        """Let the design A go (J stays): the fits after the linear ones do not use it."""
        self.__dict__.pop("design", None)
