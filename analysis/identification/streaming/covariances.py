"""The residual covariance of each test, and its whitening, for campaigns of any size.

A small campaign's are arrays (..., m, 6, 6); one of more than
:data:`~analysis.identification.streaming.blocks.EVAL_BLOCK` tests is made block by
block, and for a large one (per-test blocks made when sliced,
:mod:`analysis.identification.streaming.per_test`) when sliced
(:class:`PerTestCovariance`): the callers index them the same way.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.linalg.lsq import whitening
from analysis.identification.linalg.sandwich import per_test_diagonal
from analysis.identification.noise import residual_covariance
from analysis.identification.streaming import blocks
from analysis.identification.streaming.per_test import (
    PerTestBlocks,
    PerTestSigma,
    PerTestWhitening,
    is_lazy,
)


def covariances_per_test(noise, J, x_full, measured, w=None, weights=None,
                         out: np.ndarray | None = None) -> np.ndarray:
    """Residual covariance per test (..., m, 6, 6) at compliances x_full (..., 6).

    ``w`` (..., m, 6): the measured wrenches, for wrench noise proportional to the reading.
    ``weights`` (..., m, 6) > 0 where measured: robust weights
    (:mod:`analysis.identification.estimators.irls`); component i's variance is divided by
    weights_i and its correlations kept, Sigma_w = D^-1/2 Sigma D^-1/2 with D = diag(weights).
    One campaign (J (m, 6, 6)) is done in blocks of
    :data:`~analysis.identification.streaming.blocks.EVAL_BLOCK` tests (the (m, 6, 6)
    temporaries of 1e6 tests do not fit in cache).
    """
    if J.ndim == 3 and J.shape[0] > blocks.EVAL_BLOCK:
        # ``out``: an array to overwrite (one campaign), e.g. a covariance no longer needed
        out = np.empty(J.shape[:-1] + (6,)) if out is None else out
        for s in range(0, J.shape[0], blocks.EVAL_BLOCK):
            sl = slice(s, s + blocks.EVAL_BLOCK)
            out[sl] = covariances_per_test(noise, J[sl], x_full, measured[sl],
                                           None if w is None else w[sl],
                                           None if weights is None else weights[sl])
        return out
    C = (J * x_full[..., None, None, :]) @ np.swapaxes(J, -1, -2)  # J diag(x) J^T
    cov = residual_covariance(noise, C, w)
    if weights is not None:
        s = 1.0 / np.sqrt(np.where(measured, weights, 1.0))
        cov = cov * s[..., :, None] * s[..., None, :]
    return np.where(measured[..., :, None] & measured[..., None, :], cov, 0.0)


class PerTestCovariance(PerTestBlocks):
    """The residual covariance of each test (m, 6, 6) of one large campaign, made when sliced.

    ``cov[s:e]`` is :func:`covariances_per_test` of those tests (the same numbers as a
    slice of the whole array); the (m, 6, 6) array (0.3 GB at 1e6 tests) is never held.
    The passes over it
    (:func:`analysis.identification.linalg.sandwich.sandwich_and_residual_variance`, the
    chi-square's whitening, :func:`~analysis.identification.linalg.sandwich.per_test_diagonal`)
    take it by blocks of consecutive tests. ``J`` (m, 6, 6) is the Jacobian at the tests'
    joint angles, ``x_full`` (6,) the compliances the covariances are evaluated at.
    """

    def __init__(self, noise, J, x_full, measured, w=None, weights=None) -> None:
        self.noise, self.J, self.measured, self.w, self.weights = noise, J, measured, w, weights
        self.x_full = np.array(x_full, dtype=float)
        self.shape = J.shape[:-1] + (6,)

    def _make(self, start, stop):
        return self.take(slice(start, stop))

    def take(self, rows) -> np.ndarray:
        """The covariances of the tests ``rows`` (a slice or integer indices)."""
        def part(a):
            return None if a is None else a[rows]

        J = self.J[rows] if isinstance(rows, slice) or not isinstance(self.J, PerTestBlocks) \
            else self.J.take(rows)
        return covariances_per_test(self.noise, J, self.x_full, self.measured[rows],
                                    part(self.w), part(self.weights))


def per_test_covariance(noise, J, x_full, measured, w=None, weights=None):
    """:func:`covariances_per_test` as an array, or for one campaign of more than
    :data:`~analysis.identification.streaming.blocks.EVAL_BLOCK` tests a
    :class:`PerTestCovariance` (made block by block when used)."""
    if J.ndim == 3 and J.shape[0] > blocks.EVAL_BLOCK:
        return PerTestCovariance(noise, J, x_full, measured, w, weights)
    return covariances_per_test(noise, J, x_full, measured, w, weights)


def covariance_and_whitening(noise, J, x_full, measured, w=None, weights=None):
    """(cov, Linv): a fit's covariances (:func:`per_test_covariance`) and their whitening,
    both arrays for a small campaign, made block by block or when sliced for a larger one
    (:func:`whitening_per_test`)."""
    cov = per_test_covariance(noise, J, x_full, measured, w, weights)
    if isinstance(cov, np.ndarray):
        return cov, whitening(cov, measured)
    return cov, whitening_per_test(noise, J, x_full, measured, w, weights)


def component_sigmas(cov):
    """(m, 6) the standard deviation of each residual component (m, rad) of per-test
    covariances ``cov``: an array, or for covariances made when sliced a
    :class:`~analysis.identification.streaming.per_test.PerTestSigma` (48 MB not held at
    1e6 tests)."""
    return PerTestSigma(cov) if is_lazy(cov) else np.sqrt(per_test_diagonal(cov))


def whitening_per_test(noise, J, x_full, measured, w=None, weights=None,
                       out: np.ndarray | None = None) -> np.ndarray:
    """:func:`whitening` of :func:`covariances_per_test`, block by block for one campaign.

    The same numbers as whitening the whole covariance array, without holding it
    (one campaign of 1e6 tests: 0.3 GB, and its page faults). ``out``: a whitening
    array no longer needed, overwritten.
    """
    if J.ndim != 3 or J.shape[0] <= blocks.EVAL_BLOCK:
        return whitening(covariances_per_test(noise, J, x_full, measured, w, weights),
                         measured)
    if isinstance(J, PerTestBlocks):  # a large campaign: made when sliced, like J
        return PerTestWhitening(PerTestCovariance(noise, J, x_full, measured, w, weights),
                                measured)
    out = np.empty(J.shape[:-1] + (6,)) if out is None or out.shape != J.shape[:-1] + (6,) \
        else out
    for s in range(0, J.shape[0], blocks.EVAL_BLOCK):
        sl = slice(s, s + blocks.EVAL_BLOCK)
        out[sl] = whitening_per_test(noise, J[sl], x_full, measured[sl],
                                     None if w is None else w[sl],
                                     None if weights is None else weights[sl])
    return out
