"""The Huber robust mode: IRLS with Huber's weights around ols, wls or exact.

Huber's weights (min(1, c/|r|), c = 1.345) keep every component in the fit
at a reduced weight (:mod:`analysis.identification.estimators.irls`).
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.robust_mode import robust_refit


@dataclass(frozen=True)
class Huber:
    """Huber IRLS around ``base`` (an OLS, WLS or exact estimator)."""

    base: object
    robust: str = "huber"

    @property
    def name(self) -> str:
        return self.base.name

    @property
    def linearised(self) -> bool:
        """Around WLS the estimate is still the linear model's (its bias corrected after)."""
        return self.base.linearised

    def fit(self, problem) -> EstimatorFit:
        return robust_refit(problem, self.base, self.robust)
