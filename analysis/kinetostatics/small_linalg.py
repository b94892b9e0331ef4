"""Batched linear algebra on many small (n x n, n ~ 6) matrices, entry-major layout.

NumPy's stacked ``solve``/``inv`` call LAPACK once per matrix; for 6 x 6
systems that per-call overhead dominates. Here a batch is stored entry-major:
``A[i, j]`` is a contiguous (N,) vector over the batch, so each step of an
elimination is one vectorised operation over all N matrices.

Two kernels, each with a guard and a reference fallback:

* :func:`solve_dominant` - Gaussian elimination without pivoting, used only
  where the matrix is strictly diagonally dominant by rows (then elimination
  without pivoting is stable, growth factor at most 2); other matrices go to
  ``numpy.linalg.solve`` (partial pivoting).
* :func:`inverse_frobenius2` - ``||M^-1||_F^2 = tr((M^T M)^-1)`` from a QR
  factorisation (modified Gram-Schmidt, whose R is backward stable) and the
  inverse of the triangular factor: ``||M^-1||_F = ||R^-1||_F`` because Q is
  orthogonal. No explicit inverse of M and no Gram matrix (which would square
  the condition number).
"""

from __future__ import annotations

import numpy as np


def to_entry_major(A: np.ndarray) -> np.ndarray:
    """(N, n, m) batch -> contiguous (n, m, N) copy."""
    return np.ascontiguousarray(np.moveaxis(A, 0, -1))


def diagonally_dominant(A: np.ndarray) -> np.ndarray:
    """(N,) True where the entry-major (n, n, N) matrix is strictly row diagonally dominant."""
    n = A.shape[0]
    ok = np.ones(A.shape[2:], dtype=bool)
    # row by row: (n, N) temporaries, not an |A| as large as A (whose pages cost more to
    # touch than the sums)
    for i in range(n):
        a = np.abs(A[i])
        ok &= a[i] > a.sum(axis=0) - a[i]
    return ok


def _eliminate(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b, entry-major A (n, n, N) and b (n, N), no pivoting; A, b overwritten."""
    return _eliminate_columns(A, b[:, None, :])[:, 0, :]


def _eliminate_columns(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X with A X = B, entry-major A (n, n, N) and B (n, k, N), no pivoting; A, B overwritten.

    :func:`_eliminate` for k right-hand sides at once (one elimination of A):
    :func:`lu_em` then :func:`lu_solve_em`. The result is B itself.
    """
    return lu_solve_em(lu_em(A), B)


def lu_em(A: np.ndarray) -> np.ndarray:
    """LU factors of entry-major A (n, n, N) without pivoting, in place: U on and above the
    diagonal, the multipliers of L (unit diagonal) below. Returns A.

    Row by row with one scratch buffer: no (n, n, N) temporaries (3x faster than
    whole-block updates on 2048 systems). Stable where A is diagonally dominant.
    A may also be an augmented (n, n + k, N) array [A | B]: its last k columns are then
    eliminated with the rows, i.e. they become L^-1 B (the forward substitution of
    :func:`lu_solve_em`, the same operations in the same order).
    """
    n, width = A.shape[0], A.shape[1]
    tmp = np.empty((width,) + A.shape[2:])
    for j in range(n - 1):
        f = A[j + 1:, j]
        f /= A[j, j]  # the multipliers, over the eliminated column
        for i in range(j + 1, n):
            t = tmp[:width - j - 1]
            np.multiply(A[j, j + 1:], f[i - j - 1], out=t)
            A[i, j + 1:] -= t
    return A


def lu_solve_em(LU: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X with A X = B from :func:`lu_em` factors (n, n, N), B (n, k, N) overwritten by X."""
    n, k = LU.shape[0], B.shape[1]
    tmp = np.empty((k,) + LU.shape[2:])
    for j in range(n - 1):
        for i in range(j + 1, n):
            np.multiply(B[j], LU[i, j], out=tmp)
            B[i] -= tmp
    for i in range(n - 1, -1, -1):
        s = B[i]
        for m in range(i + 1, n):
            np.multiply(B[m], LU[i, m], out=tmp)
            s -= tmp
        s /= LU[i, i]
    return B


def lu_solve_right_em(LU: np.ndarray, D: np.ndarray) -> np.ndarray:
    """G = D A^-1 for :func:`lu_em` factors of A (n, n, N) and D (p, n, N) (new array).

    G L U = D: Z U = D column by column forward (Z = D U^-1), then G L = Z backward
    (L unit lower triangular).
    """
    n = LU.shape[0]
    G = np.array(np.moveaxis(D, 1, 0), order="C")  # (n, p, N): column j of D is G[j]
    tmp = np.empty(G.shape[1:])
    inv = 1.0 / LU[np.arange(n), np.arange(n)]  # one division per pivot, not per row of D
    for j in range(n):
        for i in range(j):
            np.multiply(G[i], LU[i, j], out=tmp)
            G[j] -= tmp
        G[j] *= inv[j]
    for j in range(n - 2, -1, -1):
        for i in range(j + 1, n):
            np.multiply(G[i], LU[i, j], out=tmp)
            G[j] -= tmp
    return np.moveaxis(G, 0, 1)


def solve_dominant_columns(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """X (..., n, k) with M X = B for batches M (..., n, n), B (..., n, k).

    One elimination without pivoting over the whole batch where every matrix is
    strictly diagonally dominant by rows (stable, growth factor at most 2);
    otherwise ``numpy.linalg.solve`` (partial pivoting) for the whole batch.
    """
    n, k = M.shape[-1], B.shape[-1]
    flat = M.reshape(-1, n, n)
    if flat.shape[0] == 0:
        return np.linalg.solve(M, B)
    Bem = np.moveaxis(np.broadcast_to(B, M.shape[:-2] + (n, k)).reshape(-1, n, k), 0, -1)
    X = solve_dominant_columns_em(to_entry_major(flat), Bem)
    return np.moveaxis(X, -1, 0).reshape(*M.shape[:-2], n, k)


def solve_dominant_columns_em(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """:func:`solve_dominant_columns` entry-major: M (n, n, N), B (n, k, N) -> X (n, k, N).

    Inputs are not modified.
    """
    if M.shape[-1] and diagonally_dominant(M).all():
        # private copies: the elimination overwrites both
        return _eliminate_columns(np.array(M, order="C"), np.array(B, order="C"))
    X = np.linalg.solve(np.moveaxis(M, -1, 0), np.moveaxis(B, -1, 0))
    return np.ascontiguousarray(np.moveaxis(X, 0, -1))


def solve_dominant(A: np.ndarray, b: np.ndarray, dominant: np.ndarray | None = None,
                   overwrite_a: bool = False) -> np.ndarray:
    """x (n, N) with A x = b for entry-major A (n, n, N), b (n, N).

    Diagonally dominant matrices are solved by elimination without pivoting;
    the others (if any) by ``numpy.linalg.solve`` with partial pivoting.
    ``dominant`` (N,) bool: :func:`diagonally_dominant` of A when the caller has it.
    ``b`` is not modified; neither is ``A`` unless ``overwrite_a`` (a caller's own
    scratch matrix, spared a copy: its content is then undefined).
    """
    ok = diagonally_dominant(A) if dominant is None else dominant
    if ok.all():
        return _eliminate(A if overwrite_a else A.copy(), b.copy())
    x = np.empty_like(b)
    if ok.any():
        x[:, ok] = _eliminate(A[:, :, ok], b[:, ok])  # boolean indexing copies
    bad = ~ok
    x[:, bad] = np.linalg.solve(
        np.moveaxis(A[:, :, bad], -1, 0), np.moveaxis(b[:, bad], -1, 0)[..., None]
    )[..., 0].T
    return x


def inverse_frobenius2(M: np.ndarray) -> np.ndarray:
    """(N,) ``||M^-1||_F^2 = tr((M^T M)^-1)`` for entry-major M (n, n, N).

    Non-finite (inf or nan) where M is exactly singular; a caller wanting a
    verdict for such matrices must use singular values.
    """
    n = M.shape[0]
    A = M.copy()  # its columns become Q's, one (n, N) column at a time
    R = np.empty(M.shape)  # only the upper triangle is written and read
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # Modified Gram-Schmidt over the columns A[:, j] (n, N): each later column loses
        # its component along q_j as soon as q_j is known.
        for j in range(n):
            a = A[:, j]
            R[j, j] = np.sqrt(np.einsum("kn,kn->n", a, a))
            a /= R[j, j]
            for m in range(j + 1, n):
                b = A[:, m]
                R[j, m] = np.einsum("kn,kn->n", a, b)
                b -= a * R[j, m]
        # ||R^-1||_F^2 column by column: column m of X = R^-1 solves R x = e_m, from the
        # bottom (x_i = 0 below m); the sum of squares on the fly, no (n, n, N) inverse.
        total = np.zeros(M.shape[-1])
        inv = 1.0 / R[np.arange(n), np.arange(n)]  # (n, N)
        x = np.empty((n,) + M.shape[2:])
        for m in range(n):
            x[m] = inv[m]
            total += x[m] * x[m]
            for i in range(m - 1, -1, -1):
                x[i] = np.einsum("kn,kn->n", R[i, i + 1:m + 1], x[i + 1:m + 1])
                x[i] *= -inv[i]
                total += x[i] * x[i]
    return total
