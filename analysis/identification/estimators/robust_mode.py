"""What the robust modes share: IRLS around a Gaussian fit, started at its estimate.

The weights, the scale and the covariance: :mod:`analysis.identification.estimators.irls`. The
chi-square, the noise-ratio notes and the validation then use the components kept
(weight >= 0.5).
"""

from __future__ import annotations

from dataclasses import replace

from analysis.identification.estimators.base import EstimatorFit
from analysis.identification.estimators.irls import robust_fit


def robust_refit(problem, base, mode: str) -> EstimatorFit:
    """``base``'s fit of ``problem``, then the ``mode`` ("huber" or "tukey") IRLS from it."""
    first = base.fit(problem)
    rob = robust_fit(problem.robot, problem.tests, problem.joints, problem.noise, base.name,
                     mode, start=first.fit.x, J=problem.jacobian)
    return replace(first, fit=rob.fit, robust=rob, kept=rob.kept(problem.tests.measured))
