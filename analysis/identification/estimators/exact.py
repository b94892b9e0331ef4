"""The exact fit: weighted Gauss-Newton on the nonlinear equilibrium model.

Started from OLS (:mod:`analysis.identification.estimators.gauss_newton`, with step halving); the
maximum-likelihood estimate under the Gaussian noise model, free of the linear model's
linearisation bias. A small campaign also gets the WLS fit, for comparison in
results.json (its first weights are the exact fit's first ones). Where the systems
are streamed (a large campaign) there is no WLS (two passes over every test for a
comparison only), and, for the Gaussian fit, the errors-in-variables S and the
validation's per-fold sums are made in the pass that forms the final system: the
problem's :class:`~analysis.identification.streaming.systems.LinearisedSystems` says
which (``compares_wls``, ``final_pass_sums``), not the campaign's size.
"""

from __future__ import annotations

from dataclasses import dataclass

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.fit_solvers import fit_exact, fit_linear
from analysis.identification.estimators.wls import ols_and_wls


@dataclass(frozen=True)
class Exact:
    """The exact estimator; ``final_pass_sums``: make the streamed fit's per-fold sums
    (False under a robust mode, whose final fit is another)."""

    name: str = "exact"
    robust: str = "none"
    linearised: bool = False
    final_pass_sums: bool = True

    def fit(self, problem) -> EstimatorFit:
        tests, systems = problem.tests, problem.systems
        first: dict = {}
        if systems.compares_wls:
            x_ols, wls = ols_and_wls(problem, first_whitening=first)
            linear = {"ols": x_ols, "wls": wls.x}
            del wls
        else:
            fit = fit_linear(problem.robot, tests, problem.joints, problem.noise,
                             weighted=False, design=problem.design)
            linear = {"ols": fit.x}
            del fit
        problem.release_design()
        sums = systems.final_pass_sums(problem) if self.final_pass_sums else None
        # the first Gauss-Newton weights are WLS's first ones (both at the OLS estimate)
        fit = fit_exact(problem.robot, tests, problem.joints, problem.noise,
                        start=linear["ols"], first_whitening=first or None, sums=sums,
                        J=problem.jacobian)
        return EstimatorFit(fit=fit, linear=linear, kept=tests.measured, sums=sums)
