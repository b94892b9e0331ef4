"""Weighted least squares of the linear model.

Each test weighted by its inverse measurement covariance
(:func:`analysis.identification.noise.residual_covariance`: the instrument sigmas plus
the wrench noise propagated through the Cartesian compliance at the current estimate),
two reweighting passes from the OLS estimate
(:func:`analysis.identification.estimators.fit_solvers.fit_linear`).
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.fit_solvers import fit_linear


def ols_and_wls(problem, first_whitening: dict | None = None):
    """(OLS fit's x, WLS fit) on the problem's design; ``first_whitening`` receives the
    first WLS pass's {x, Linv} (an exact fit started at the same x reuses it). The OLS
    fit is let go before the WLS one is made (its per-test arrays are ~1 kB per test)."""
    ols = fit_linear(problem.robot, problem.tests, problem.joints, problem.noise,
                     weighted=False, design=problem.design)
    x_ols = ols.x
    del ols
    # WLS's weights start at the uncorrected OLS estimate (it solves that itself: the OLS
    # fit's x is the errors-in-variables corrected one)
    wls = fit_linear(problem.robot, problem.tests, problem.joints, problem.noise,
                     weighted=True, design=problem.design, first_whitening=first_whitening)
    return x_ols, wls


@dataclass(frozen=True)
class WLS:
    """The WLS estimator."""

    name: str = "wls"
    robust: str = "none"
    linearised: bool = True

    def fit(self, problem) -> EstimatorFit:
        x_ols, fit = ols_and_wls(problem)
        problem.release_design()
        return EstimatorFit(fit=fit, linear={"ols": x_ols, "wls": fit.x},
                            kept=problem.tests.measured)
