"""The covariance of a linear(ised) estimate and each residual's variance, block by block.

For x = G d with G = bread A^T W (per-test blocks A (m, 6, p), whitening Linv, W = Linv^T
Linv; :class:`~analysis.identification.estimators.fit_record.Fit`): the sandwich G Sigma G^T and
the variances of the residuals d - A x, in passes over blocks of tests, never forming G
or the (6m, 6m) hat matrix.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.linalg.lsq import TEST_BLOCK


def sandwich(A: np.ndarray, cov: np.ndarray, bread: np.ndarray,
             Linv: np.ndarray | None = None, block: int = TEST_BLOCK) -> np.ndarray:
    """Covariance (p, p) of x = G d, G = bread A^T W, from per-test blocks.

    A (m, 6, p) design (zero rows where not measured), cov (m, 6, 6) residual
    covariance Sigma, W = Linv^T Linv (identity for OLS, ``Linv`` None).
    ``bread (sum A^T W Sigma W A) bread`` summed over tests in blocks: equal to
    G Sigma G^T without the p x 6m matrix G.
    """
    p = A.shape[-1]
    meat = np.zeros((p, p))
    for s in range(0, A.shape[0], block):
        WA = _weighted(A, Linv, s, block)
        meat += WA.reshape(-1, p).T @ (cov[s:s + block] @ WA).reshape(-1, p)
    return bread @ meat @ bread.T


def _weighted(A, Linv, s, block):
    """W A = Linv^T Linv A for the tests s:s+block (A itself when Linv is None)."""
    Ab = A[s:s + block]
    if Linv is None:
        return Ab
    Lb = Linv[s:s + block]
    return np.swapaxes(Lb, -1, -2) @ (Lb @ Ab)


def residual_variance_blocks(A: np.ndarray, cov: np.ndarray, bread: np.ndarray,
                             cov_x: np.ndarray, Linv: np.ndarray | None = None,
                             block: int = TEST_BLOCK) -> np.ndarray:
    """diag Var(r) (m, 6) of the residuals r = (I - A G) e of x = G d, G = bread A^T W.

    Per test i: ``diag(Sigma_i) - 2 diag(A_i G_i Sigma_i) + diag(A_i cov_x A_i^T)``
    with ``G_i = bread A_i^T W_i`` -- the diagonal blocks of the hat-matrix
    expression of :func:`analysis.identification.uncertainty.residual_variance`,
    without forming the hat matrix (or G).
    """
    m = A.shape[0]
    out = np.empty((m, 6))
    for s in range(0, m, block):
        Ab, Sb = A[s:s + block], cov[s:s + block]
        p = Ab.shape[-1]
        SWA = Sb @ _weighted(A, Linv, s, block)  # (G_i Sigma_i)^T = Sigma_i W_i A_i bread
        cross = np.sum((Ab.reshape(-1, p) @ bread).reshape(Ab.shape) * SWA, axis=-1)
        quad = np.sum((Ab.reshape(-1, p) @ cov_x).reshape(Ab.shape) * Ab, axis=-1)
        out[s:s + block] = np.maximum(np.diagonal(Sb, axis1=-2, axis2=-1) - 2 * cross + quad,
                                      0.0)
    return out


def sandwich_and_residual_variance(A: np.ndarray, cov, bread: np.ndarray,
                                   Linv: np.ndarray | None = None, block: int = TEST_BLOCK,
                                   meat: np.ndarray | None = None, own_weights: bool = False,
                                   visit=None
                                   ) -> tuple[np.ndarray, np.ndarray]:
    """(:func:`sandwich`, :func:`residual_variance_blocks`) with one pass over ``cov``.

    The same numbers as the two calls: the per-test part that needs Sigma_i,
    ``diag(Sigma_i) - 2 diag(A_i G_i Sigma_i)``, is made in the pass that sums the
    sandwich's meat; ``diag(A_i cov_x A_i^T)`` is added once cov_x is known (a pass over
    A only). ``cov`` may be made block by block when sliced
    (:class:`analysis.identification.streaming.covariances.PerTestCovariance`): it is sliced once
    per block of tests.

    ``meat`` (p, p): sum A^T W Sigma W A if the caller knows it (a fit whitened by its
    own covariances: A^T W A, from its system's R); the variances then take one pass,
    which can also: take Sigma W A = A (``own_weights``: W is the whitening of ``cov``,
    so Sigma_i W_i = I on the measured components, and A is zero on the others: no
    whitening is made); and call ``visit(slice, A block)`` for each block of tests (the
    caller's per-test work on the same blocks of A, made once).
    """
    m, p = A.shape[0], A.shape[-1]
    if meat is not None:
        cov_x = bread @ meat @ bread.T
        part = np.empty((m, 6))
        for s in range(0, m, block):
            Ab, Sb = A[s:s + block], cov[s:s + block]
            SWA = Ab if own_weights else Sb @ _weighted(A, Linv, s, block)
            if visit is not None:
                visit(slice(s, s + block), Ab)
            flat = Ab.reshape(-1, p)
            cross = np.sum((flat @ bread).reshape(Ab.shape) * SWA, axis=-1)
            quad = np.sum((flat @ cov_x).reshape(Ab.shape) * Ab, axis=-1)
            part[s:s + block] = np.maximum(np.diagonal(Sb, axis1=-2, axis2=-1) - 2 * cross
                                           + quad, 0.0)
        return cov_x, part
    meat = np.zeros((p, p))
    part = np.empty((m, 6))
    for s in range(0, m, block):
        Ab, Sb = A[s:s + block], cov[s:s + block]
        WA = _weighted(A, Linv, s, block)
        SWA = Sb @ WA
        meat += WA.reshape(-1, p).T @ SWA.reshape(-1, p)
        cross = np.sum((Ab.reshape(-1, p) @ bread).reshape(Ab.shape) * SWA, axis=-1)
        part[s:s + block] = np.diagonal(Sb, axis1=-2, axis2=-1) - 2 * cross
    cov_x = bread @ meat @ bread.T
    for s in range(0, m, block):
        Ab = A[s:s + block]
        quad = np.sum((Ab.reshape(-1, p) @ cov_x).reshape(Ab.shape) * Ab, axis=-1)
        part[s:s + block] = np.maximum(part[s:s + block] + quad, 0.0)
    return cov_x, part


def per_test_diagonal(cov, block: int = TEST_BLOCK) -> np.ndarray:
    """diag of each test's 6 x 6 block, (m, 6), from ``cov`` (m, 6, 6) sliced by blocks."""
    m = cov.shape[0]
    out = np.empty((m, 6))
    for s in range(0, m, block):
        out[s:s + block] = np.diagonal(cov[s:s + block], axis1=-2, axis2=-1)
    return out
