"""Ordinary least squares of the linear model (the paper's estimator, eqs. 16-21).

Unweighted least squares on the stacked A (6m x p), by QR of the column-scaled A (no
normal equations), corrected for the wrench noise in the regressor; its covariance is
the sandwich A^+ Sigma A^+T with Sigma from the noise model
(:func:`analysis.identification.estimators.fit_solvers.fit_linear`).
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.fit_solvers import fit_linear


@dataclass(frozen=True)
class OLS:
    """The OLS estimator."""

    name: str = "ols"
    robust: str = "none"
    linearised: bool = True

    def fit(self, problem) -> EstimatorFit:
        fit = fit_linear(problem.robot, problem.tests, problem.joints, problem.noise,
                         weighted=False, design=problem.design)
        problem.release_design()
        return EstimatorFit(fit=fit, linear={"ols": fit.x}, kept=problem.tests.measured)
