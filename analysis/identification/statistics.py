"""A fit's statistics: the covariance of x, each residual's variance, the chi-square.

Two implementations of one pass over the tests: :func:`final_pass_statistics`, from the
triangular factor R of the final whitened system that a streamed exact fit carries (its
per-test blocks made when sliced), and :func:`held_statistics` for every other fit (held
blocks, a linear model's fit, a robust fit: a pass of its own, block by block). Which one
serves a fit is the problem's
:class:`~analysis.identification.streaming.systems.LinearisedSystems`'s to say
(:meth:`~analysis.identification.streaming.systems.LinearisedSystems.statistics`):
:func:`fit_statistics` does not ask how the fit holds its system.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.linalg.lsq import StackedRows, blocks_of_tests, whitening
from analysis.identification.linalg.sandwich import sandwich_and_residual_variance
from analysis.identification.uncertainty import chi2_summary


@dataclass(frozen=True)
class FitStatistics:
    """cov_x (p, p): the sandwich covariance of x under the noise model ((rad/(N m))^2,
    unscaled); var_r (m, 6): each residual's variance (m^2, rad^2); chi2_reduced,
    p_value, dof: the goodness of fit on the components kept; Aw: a matrix with the
    singular values of the whitened system (its R, or the stacked whitened design)."""

    cov_x: np.ndarray
    var_r: np.ndarray
    chi2_reduced: float
    p_value: float
    dof: int
    Aw: np.ndarray


def fit_statistics(problem, outcome):
    """(statistics, outcome): the :class:`FitStatistics` of ``outcome`` (an
    :class:`~analysis.identification.estimators.base.EstimatorFit`) of ``problem``, and
    the outcome the later stages use (a streamed fit's gets the prediction its pass
    made; others are returned as they are), by the problem's systems
    (:meth:`~analysis.identification.streaming.systems.LinearisedSystems.statistics`)."""
    return problem.systems.statistics(problem, outcome)


def degrees_of_freedom(problem, outcome) -> int:
    """The chi-square's degrees of freedom: the components the fit rests on less p."""
    return int(outcome.kept.sum()) - problem.p


def final_pass_statistics(problem, outcome):
    """(statistics, outcome) of a fit that carries the factor R of its final whitened
    system (a streamed exact fit, whitened by its own covariances): one pass over the
    recomputed blocks gives the variances (meat A^T W A = R^T R, and Sigma W A = A), each
    component's sigma, and the prediction moved by the errors-in-variables shift, which
    the new outcome's fit carries (its F's later blocks start cold)."""
    from dataclasses import replace

    chosen, dof = outcome.fit, degrees_of_freedom(problem, outcome)
    p = problem.p
    Rp, c0 = chosen.R[:p, :p], chosen.R[:p, p]
    predicted = chosen.predicted
    fill = predicted is None  # the model's values come with A's blocks
    if fill:
        predicted = np.empty(problem.tests.measured.shape)
    move = None if chosen.predicted_shifted else chosen.eiv_shift

    def visit(sl, Ab):
        if fill:
            predicted[sl] = chosen.A.values(sl)
        if move is not None:
            predicted[sl] += Ab @ move

    cov_x, var_r = sandwich_and_residual_variance(
        chosen.A, chosen.cov, chosen.bread, chosen.Linv, meat=Rp.T @ Rp,
        own_weights=True, visit=visit)
    # later rows (outliers' leverages) start cold: the deflections' 48 MB let go
    done = replace(chosen, predicted=predicted, predicted_shifted=True, A=chosen.A.cold())
    # chi-square from R: |Linv (r - F shift)|^2 = |c0 - Rp shift|^2 + R[p, p]^2
    shift = np.zeros(p) if chosen.eiv_shift is None else chosen.eiv_shift
    chi2_red, p_value = chi2_summary(float(np.sum((c0 - Rp @ shift) ** 2)
                                           + chosen.R[p, p] ** 2), dof)
    return (FitStatistics(cov_x, var_r, chi2_red, p_value, dof, Rp),
            replace(outcome, fit=done))


def held_statistics(problem, outcome) -> FitStatistics:
    """The sandwich and residual variances of the fit's blocks, and the chi-square summed
    block by block (no (m, 6) residual arrays): any fit, its blocks held or made when
    sliced."""
    tests, chosen, kept = problem.tests, outcome.fit, outcome.kept
    dof = degrees_of_freedom(problem, outcome)
    p = problem.p
    cov_x, var_r = sandwich_and_residual_variance(chosen.A, chosen.cov, chosen.bread,
                                                  chosen.Linv)
    # the fit's own whitening when it used the same components, else made block by
    # block (an (m, 6, 6) array is 0.3 GB at 1e6 tests); the same pass gives the whitened
    # system (a tall one's R), for its scaled condition without the (6m, p) Linv A
    own = chosen.Linv if outcome.robust is None and chosen.Linv is not None else None
    acc = StackedRows(6 * tests.m)
    chi2 = 0.0
    for sl in blocks_of_tests(tests.m):
        Lb = own[sl] if own is not None else whitening(chosen.cov[sl], kept[sl])
        rb = np.where(kept[sl], tests.d[sl] - chosen.predicted[sl], 0.0)
        chi2 += float(np.sum(np.einsum("mij,mj->mi", Lb, rb) ** 2))
        acc.add((Lb @ chosen.A[sl]).reshape(-1, p))
    chi2_red, p_value = chi2_summary(chi2, dof)
    return FitStatistics(cov_x, var_r, chi2_red, p_value, dof, acc.matrix())
