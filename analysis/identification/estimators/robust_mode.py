"""The robust modes: IRLS around a Gaussian fit (ols, wls or exact), started at its estimate.

One estimator, :class:`RobustMode`, for both modes; what tells them apart is data: the
mode's name, which selects its weights in :mod:`analysis.identification.estimators.irls`
(with the scale and the covariance), described in :data:`MODES`. The chi-square, the
noise-ratio notes and the validation then use the components kept (weight >= 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from types import MappingProxyType

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.irls import robust_fit

#: the robust modes (``--robust``) by name, each with what its weights do
MODES = MappingProxyType({
    "huber": "Huber's weights min(1, c/|r|), c = 1.345: every component stays in the fit, "
             "at a reduced weight",
    "tukey": "Tukey's biweight (1 - (r/c)^2)^2 within c = 4.685, else 0, from Huber's "
             "solution: gross errors are set aside",
})


def robust_refit(problem, base, mode: str) -> EstimatorFit:
    """``base``'s fit of ``problem``, then the ``mode`` ("huber" or "tukey") IRLS from it."""
    first = base.fit(problem)
    rob = robust_fit(problem.robot, problem.tests, problem.joints, problem.noise, base.name,
                     mode, start=first.fit.x, J=problem.jacobian)
    return replace(first, fit=rob.fit, robust=rob, kept=rob.kept(problem.tests.measured))


@dataclass(frozen=True)
class RobustMode:
    """The IRLS of mode ``robust`` (a name of :data:`MODES`) around ``base`` (an OLS, WLS
    or exact estimator)."""

    base: object
    robust: str

    def __post_init__(self) -> None:
        if self.robust not in MODES:
            raise ValueError(f"unknown robust mode {self.robust!r}; expected one of "
                             f"{', '.join(MODES)}")

    @property
    def name(self) -> str:
        return self.base.name

    @property
    def linearised(self) -> bool:
        """Around WLS the estimate is still the linear model's (its bias corrected after)."""
        return self.base.linearised

    def fit(self, problem) -> EstimatorFit:
        return robust_refit(problem, self.base, self.robust)
