"""The estimator interface: what every estimator of the compliances does, and returns.

An estimator fits the compliances x (rad/(N m)) of the problem's joints to its tests
(:class:`~analysis.identification.problem.IdentificationProblem`). It does not know the
campaign's size: the per-test blocks it works on (J, the design, the covariances) are
held arrays for a small campaign and made when sliced for a large one
(:mod:`analysis.identification.streaming.per_test`), behind the same indexing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from analysis.identification.estimators.fit_record import Fit


@dataclass(frozen=True)
class EstimatorFit:
    """An estimator's outcome.

    fit: the chosen fit (x, its per-test model and covariances, the factored estimator);
    linear: the linear fits made on the way ({"ols": x, "wls": x}, rad/(N m)), listed in
    results.json; kept (m, 6) bool: the components the fit rests on (a robust fit's
    weight >= 0.5, else the measured ones); robust: the robust fit
    (:class:`~analysis.identification.estimators.irls.RobustFit`) or None; sums: a streamed
    exact fit's per-fold sums, made in its final pass
    (:class:`~analysis.identification.streaming.fold_sums.FinalPassSums`) or None.
    """

    fit: Fit
    linear: dict[str, np.ndarray]
    kept: np.ndarray
    robust: object | None = None
    sums: object | None = field(default=None, repr=False)


class Estimator(Protocol):
    """Fits the compliances of an identification problem.

    ``name``: as in results.json ``method`` (the Gaussian fit a robust mode runs
    around); ``robust``: "none" or the robust mode; ``linearised``: the fit is of the
    linear model, whose linearisation bias is corrected afterwards
    (:mod:`analysis.identification.corrections.linear_bias`).
    """

    name: str
    robust: str
    linearised: bool

    def fit(self, problem) -> EstimatorFit:
        """Fit ``problem`` (an :class:`~analysis.identification.problem.IdentificationProblem`)."""
        ...
