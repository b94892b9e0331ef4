"""The Tukey robust mode: IRLS with Tukey's weights around ols, wls or exact.

Tukey's biweight ((1 - (r/c)^2)^2 within c = 4.685, else 0), from Huber's solution,
sets gross errors aside (:mod:`analysis.identification.estimators.irls`).
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.robust_mode import robust_refit


@dataclass(frozen=True)
class Tukey:
    """Tukey IRLS around ``base`` (an OLS, WLS or exact estimator)."""

    base: object
    robust: str = "tukey"

    @property
    def name(self) -> str:
        return self.base.name

    @property
    def linearised(self) -> bool:
        """Around WLS the estimate is still the linear model's (its bias corrected after)."""
        return self.base.linearised

    def fit(self, problem) -> EstimatorFit:
        return robust_refit(problem, self.base, self.robust)
