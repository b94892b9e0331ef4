"""Least-squares kernels for many small systems at once, batch on the LAST axis.

np.linalg.qr / cholesky make one LAPACK call per matrix, which dominates for
1e5 systems of 30 x 6. Here the few steps of QR (modified Gram-Schmidt),
Cholesky and triangular substitution are written out with the batch as the last,
contiguous axis, so each step is one vectorised operation over all trials.
Arrays: matrices by column (p, r, T) or (k, k, ...), vectors (r, T).
"""

from __future__ import annotations

import numpy as np

CHUNK = 1024  # trials per block: keeps the working set in cache


def mgs_lstsq(
    A: np.ndarray, d: np.ndarray, with_rinv: bool = True, chunk: int = CHUNK
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Least squares A x ~ d by modified Gram-Schmidt QR of the column-scaled [A | d].

    MGS applied to the augmented matrix gives a backward-stable least-squares
    solution (Bjorck 1967) without forming Q or the normal equations.

    Parameters
    ----------
    A : (p, r, T) design matrices stored by column; d : (r, T) right-hand sides.
    with_rinv : also return R^-1 (for covariances).

    Returns
    -------
    x : (p, T); Rinv : (p, p, T) or None, inverse triangular factor of the
    column-scaled A; scale : (p, T) column norms, so that
    (A^T A)^-1 = Rinv Rinv^T / (scale scale^T).
    """
    p, r, T = A.shape
    x = np.empty((p, T))
    Rinv = np.empty((p, p, T)) if with_rinv else None
    scale = np.empty((p, T))
    for s in range(0, T, chunk):
        sl = slice(s, min(T, s + chunk))
        xs, ri, sc = _mgs_block(A[..., sl], d[..., sl], with_rinv)
        x[:, sl], scale[:, sl] = xs, sc
        if with_rinv:
            Rinv[..., sl] = ri
    return x, Rinv, scale


def _mgs_block(A, d, with_rinv):
    p, r, T = A.shape
    V = np.empty((p + 1, r, T))
    V[:p] = A
    V[p] = d
    scale = np.sqrt(np.einsum("crt,crt->ct", A, A))
    scale = np.where(scale > 0, scale, 1.0)
    V[:p] /= scale[:, None, :]
    R = np.zeros((p, p + 1, T))
    for j in range(p):
        nj = np.sqrt(np.einsum("rt,rt->t", V[j], V[j]))
        R[j, j] = nj
        V[j] /= np.where(nj > 0, nj, 1.0)
        c = np.einsum("rt,crt->ct", V[j], V[j + 1:])
        R[j, j + 1:] = c
        V[j + 1:] -= V[j][None] * c[:, None, :]
    xs = np.zeros((p, T))
    for i in range(p - 1, -1, -1):
        xs[i] = (R[i, p] - np.einsum("jt,jt->t", R[i, i + 1:p], xs[i + 1:])) / R[i, i]
    Rinv = None
    if with_rinv:
        Rinv = np.zeros((p, p, T))
        eye = np.eye(p)[:, :, None]
        for i in range(p - 1, -1, -1):
            acc = eye[i] - np.einsum("jt,jct->ct", R[i, i + 1:p], Rinv[i + 1:])
            Rinv[i] = acc / R[i, i]
    return xs / scale, Rinv, scale


def cholesky(S: np.ndarray, check: bool = False) -> np.ndarray:
    """Lower Cholesky factor (k, k, ...) of symmetric positive definite S (k, k, ...).

    Column by column over the whole batch (each update one vectorised operation on the
    rows below the diagonal). ``check``: raise ``numpy.linalg.LinAlgError`` when a pivot
    is <= 0 (S not positive definite), as ``numpy.linalg.cholesky`` does (NaN pivots
    propagate without raising, as there); otherwise such a factor holds NaN.
    """
    k = S.shape[0]
    L = np.zeros(S.shape)
    for j in range(k):
        c = np.array(S[j:, j], dtype=float)  # column j from the diagonal down
        for m in range(j):
            c -= L[j:, m] * L[j, m]
        if check and np.any(c[0] <= 0.0):
            raise np.linalg.LinAlgError("Matrix is not positive definite")
        L[j, j] = np.sqrt(c[0])
        # times the reciprocal of the pivot (as LAPACK's potf2): cheaper than k divisions
        np.multiply(c[1:], 1.0 / L[j, j], out=L[j + 1:, j])
    return L


def lower_inverse(L: np.ndarray) -> np.ndarray:
    """Inverse (k, k, ...) of lower-triangular L (k, k, ...), batch on the trailing axes.

    Row by row, ``X[i, j] = -sum_{m=j}^{i-1} L[i, m] X[m, j] / L[i, i]`` for all j < i at
    once (only the structurally nonzero terms, summed in increasing m).
    """
    k = L.shape[0]
    X = np.zeros(L.shape)
    inv = 1.0 / np.diagonal(L, axis1=0, axis2=1)  # (..., k)
    inv = np.moveaxis(inv, -1, 0)
    for i in range(k):
        X[i, i] = inv[i]
        if i:
            acc = np.zeros((i,) + L.shape[2:])
            tmp = np.empty(acc.shape)
            for m in range(i):
                np.multiply(X[m, :m + 1], L[i, m], out=tmp[:m + 1])
                acc[:m + 1] += tmp[:m + 1]
            np.multiply(acc, -inv[i], out=X[i, :i])
    return X


def forward_substitute(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """L^-1 B for lower-triangular L (k, k, ...) and B (k, ...) or (k, c, ...).

    The trailing axes of L broadcast against those of each B[i].
    """
    k = L.shape[0]
    X = np.empty((k,) + np.broadcast_shapes(B.shape[1:], L.shape[2:]))
    for i in range(k):
        acc = np.array(B[i], dtype=float)
        for m in range(i):
            acc -= L[i, m] * X[m]
        X[i] = acc / L[i, i]
    return X
