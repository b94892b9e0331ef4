"""Batched least squares by QR on column-scaled, whitened systems.

All functions are pure and batched over leading axes, so the same code fits
one campaign and 1e5 Monte-Carlo trials. No normal equations are formed: the
solution comes from the QR factors of the column-scaled matrix, and its
covariance from R^-1.
"""

from __future__ import annotations

import numpy as np


def column_scale(A: np.ndarray) -> np.ndarray:
    """Euclidean norm of each column of A (..., r, p); 1 where a column is zero."""
    s = np.linalg.norm(A, axis=-2)
    return np.where(s > 0, s, 1.0)


def scaled_condition(A: np.ndarray) -> np.ndarray:
    """2-norm condition number of A (..., r, p) after scaling each column to unit norm.

    ``inf`` when a column is zero or A is rank deficient to working precision.
    """
    norms = np.linalg.norm(A, axis=-2)
    s = np.linalg.svd(A / np.where(norms > 0, norms, 1.0)[..., None, :], compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(s[..., -1] > s[..., 0] * 1e-15, s[..., 0] / s[..., -1], np.inf)
    return np.where(np.all(norms > 0, axis=-1), cond, np.inf)


def weakest_column(A: np.ndarray) -> int:
    """Index of the column most involved in the near-null space of column-scaled A (r, p)."""
    norms = np.linalg.norm(A, axis=0)
    if np.any(norms == 0):
        return int(np.flatnonzero(norms == 0)[0])
    _, _, vt = np.linalg.svd(A / norms, full_matrices=False)
    return int(np.argmax(np.abs(vt[-1])))


def qr_solve(A: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least-squares solution of A x ~ d, batched: A (..., r, p), d (..., r).

    Returns
    -------
    x : (..., p) solution.
    cov_unit : (..., p, p) (A^T A)^-1, from R^-1 of the column-scaled QR.
    pinv : (..., p, r) the left inverse A^+ = R^-1 Q^T (unscaled), so x = A^+ d.
    """
    scale = column_scale(A)
    Q, R = np.linalg.qr(A / scale[..., None, :])
    Rinv = np.linalg.inv(R)
    pinv = (Rinv @ np.swapaxes(Q, -1, -2)) / scale[..., :, None]
    x = np.einsum("...pr,...r->...p", pinv, d)
    cov_unit = (Rinv @ np.swapaxes(Rinv, -1, -2)) / (scale[..., :, None] * scale[..., None, :])
    return x, cov_unit, pinv


def whitening(cov: np.ndarray, measured: np.ndarray | None = None) -> np.ndarray:
    """Inverse Cholesky factors L^-1 (..., 6, 6) of per-test covariances (..., 6, 6).

    Components not ``measured`` (bool (..., 6)) are decoupled and their rows
    of L^-1 zeroed, so they drop out of a whitened system.
    """
    cov = np.array(cov, dtype=float)
    if measured is not None:
        keep = measured[..., :, None] & measured[..., None, :]
        eye = np.broadcast_to(np.eye(6, dtype=bool), keep.shape)
        cov = np.where(keep, cov, np.where(eye, 1.0, 0.0))
    Linv = np.linalg.inv(np.linalg.cholesky(cov))
    if measured is not None:
        Linv = Linv * measured[..., :, None]
    return Linv


def stack_matrix(blocks: np.ndarray) -> np.ndarray:
    """Per-test blocks (..., m, 6, p) -> stacked rows (..., 6 m, p)."""
    return blocks.reshape(*blocks.shape[:-3], -1, blocks.shape[-1])


def stack_vector(blocks: np.ndarray) -> np.ndarray:
    """Per-test vectors (..., m, 6) -> stacked rows (..., 6 m)."""
    return blocks.reshape(*blocks.shape[:-2], -1)


def block_diag_apply(G: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """G Sigma for G (..., p, 6m) and block-diagonal Sigma given as blocks (..., m, 6, 6)."""
    Gb = G.reshape(*G.shape[:-1], cov.shape[-3], 6)
    return np.einsum("...pmi,...mij->...pmj", Gb, cov).reshape(G.shape)

