"""Uncertainty of identified joint stiffness: intervals, residual statistics.

Confidence intervals
--------------------
The estimator is (nearly) linear and Gaussian in the compliances x = 1/k, not
in k. The 95 % interval of x_j is ``x_j +- c se(x_j)`` (c = 1.96 with the
noise-model covariance, Student t with the residual-scaled one), and the
interval of k_j is its image through the decreasing map 1/x:
``[1/(x + c se), 1/(x - c se)]`` -- exact coverage is preserved by a monotone
map. When the x interval reaches 0 the upper bound of k is infinite (the data
cannot rule out a rigid joint). ``se(k_j) = se(x_j) / x_j^2`` (delta method)
is reported as a standard error only.
"""

from __future__ import annotations

import numpy as np

# scipy.special, not scipy.stats: the same functions (scipy.stats' t, norm and chi2
# call these), without the ~0.4 s import of scipy.stats at every analysis.
from scipy import special


def critical_value(confidence: float = 0.95, dof=None):
    """Two-sided critical value: normal, or Student t with ``dof`` degrees of freedom
    (a number, or an array of them: one value each; inf gives the normal's)."""
    p = 0.5 + confidence / 2.0
    if dof is None:
        return float(special.ndtri(p))
    if np.ndim(dof):
        dof = np.asarray(dof, dtype=float)
        return np.where(np.isfinite(dof), special.stdtrit(np.where(np.isfinite(dof), dof, 1.0),
                                                          p), special.ndtri(p))
    return float(special.stdtrit(dof, p))


def interval_critical_value(confidence: float, covariance: str = "model", dof: int = 0,
                            robust_dof=None):
    """The critical value of a fit's reported intervals: Student t with each joint's
    Satterthwaite ``robust_dof`` (p,) for a robust fit; t with the residual ``dof`` when
    the covariance is scaled by the residuals (``covariance`` "residual", dof > 0); else
    the normal's (the noise figures taken as known)."""
    if robust_dof is not None:
        return critical_value(confidence, np.asarray(robust_dof, dtype=float))
    if covariance == "residual" and dof > 0:
        return critical_value(confidence, dof)
    return critical_value(confidence)


def stiffness_interval(x: np.ndarray, se_x: np.ndarray, c: float) -> np.ndarray:
    """(..., 2) interval [lo, hi] of k = 1/x (N m/rad), mapped from the x interval.

    ``hi = inf`` when the x interval contains 0; both NaN when the whole x
    interval is <= 0 (no positive stiffness is consistent with the data).
    """
    lo_x, hi_x = x - c * se_x, x + c * se_x
    with np.errstate(divide="ignore", invalid="ignore"):
        lo = np.where(hi_x > 0, 1.0 / hi_x, np.nan)
        hi = np.where(lo_x > 0, 1.0 / lo_x, np.where(hi_x > 0, np.inf, np.nan))
    return np.stack([lo, hi], axis=-1)


def residual_variance(
    A: np.ndarray, sigma_G: np.ndarray, diag_sigma: np.ndarray, cov_x: np.ndarray
) -> np.ndarray:
    """diag Var(r) (..., r) of residuals r = (I - A G) e of a linear estimator x = G d.

    ``Var(r) = Sigma - A G Sigma - (A G Sigma)^T + A cov_x A^T``; ``sigma_G`` is
    G Sigma (p, r), ``diag_sigma`` diag(Sigma) (r,). Exact for OLS and WLS,
    first order for the Gauss-Newton fit (A its Jacobian at the solution).
    """
    cross = np.einsum("...rp,...pr->...r", A, sigma_G)
    quad = np.einsum("...rp,...pq,...rq->...r", A, cov_x, A)
    return np.maximum(diag_sigma - 2.0 * cross + quad, 0.0)


def studentized(residual: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """residual / sqrt(variance); NaN where the variance is 0 (a fully determined row)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(variance > 0, residual / np.sqrt(variance), np.nan)


def chi2_summary(whitened_residual: np.ndarray | float, dof: int) -> tuple[float, float]:
    """(reduced chi-square, p-value of the chi-square test) for whitened residuals, or
    for their sum of squares given as a float."""
    chi2 = float(whitened_residual) if np.ndim(whitened_residual) == 0 else float(
        np.sum(whitened_residual**2))
    if dof <= 0:
        return float("nan"), float("nan")
    return chi2 / dof, float(special.chdtrc(dof, chi2))
