"""Batched least squares by QR on column-scaled, whitened systems.

All functions are pure and batched over leading axes, so the same code fits
one campaign and 1e5 Monte-Carlo trials. No normal equations are formed: the
solution comes from the QR factors of the column-scaled matrix, and its
covariance from R^-1.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.linalg import batch_lsq


def column_scale(A: np.ndarray) -> np.ndarray:
    """Euclidean norm of each column of A (..., r, p); 1 where a column is zero."""
    s = np.linalg.norm(A, axis=-2)
    return np.where(s > 0, s, 1.0)


def scaled_condition(A: np.ndarray) -> np.ndarray:
    """2-norm condition number of A (..., r, p) after scaling each column to unit norm.

    ``inf`` when a column is zero or A is rank deficient to working precision.
    A tall 2-D A is reduced to its triangular factor first (same singular values).
    """
    norms = np.linalg.norm(A, axis=-2)
    if A.ndim == 2 and A.shape[0] > TALL_ROWS:
        A = tall_r(A)
    s = np.linalg.svd(A / np.where(norms > 0, norms, 1.0)[..., None, :], compute_uv=False)
    with np.errstate(divide="ignore"):
        cond = np.where(s[..., -1] > s[..., 0] * 1e-15, s[..., 0] / s[..., -1], np.inf)
    return np.where(np.all(norms > 0, axis=-1), cond, np.inf)


def weakest_column(A: np.ndarray) -> int:
    """Index of the column most involved in the near-null space of column-scaled A (r, p)."""
    norms = np.linalg.norm(A, axis=0)
    if np.any(norms == 0):
        return int(np.flatnonzero(norms == 0)[0])
    if A.shape[0] > TALL_ROWS:
        A = tall_r(A)  # same right singular vectors
    _, _, vt = np.linalg.svd(A / norms, full_matrices=False)
    return int(np.argmax(np.abs(vt[-1])))


def qr_solve(A: np.ndarray, d: np.ndarray, with_pinv: bool = True
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Least-squares solution of A x ~ d, batched: A (..., r, p), d (..., r).

    Returns
    -------
    x : (..., p) solution.
    cov_unit : (..., p, p) (A^T A)^-1, from R^-1 of the column-scaled QR.
    pinv : (..., p, r) the left inverse A^+ = R^-1 Q^T (unscaled), so x = A^+ d;
        None when ``with_pinv`` is False (then a tall 2-D A, more than
        :data:`TALL_ROWS` rows, is solved blockwise by :func:`tall_solve`).
    """
    if not with_pinv and A.ndim == 2 and A.shape[0] > TALL_ROWS:
        x, cov_unit = tall_solve(A, d)
        return x, cov_unit, None
    scale = column_scale(A)
    Q, R = np.linalg.qr(A / scale[..., None, :])
    Rinv = np.linalg.inv(R)
    cov_unit = (Rinv @ np.swapaxes(Rinv, -1, -2)) / (scale[..., :, None] * scale[..., None, :])
    if not with_pinv:
        z = np.einsum("...rp,...r->...p", Q, d)
        return np.einsum("...pq,...q->...p", Rinv, z) / scale, cov_unit, None
    pinv = (Rinv @ np.swapaxes(Q, -1, -2)) / scale[..., :, None]
    x = np.einsum("...pr,...r->...p", pinv, d)
    return x, cov_unit, pinv


def whitening(cov: np.ndarray, measured: np.ndarray | None = None,
              out: np.ndarray | None = None) -> np.ndarray:
    """Inverse Cholesky factors L^-1 (..., 6, 6) of per-test covariances (..., 6, 6).

    Components not ``measured`` (bool (..., 6)) are decoupled and their rows
    of L^-1 zeroed, so they drop out of a whitened system. Raises
    ``numpy.linalg.LinAlgError`` when a (decoupled) covariance is not positive definite,
    as ``numpy.linalg.cholesky``. Entry-major Cholesky factorisation and triangular
    inverse over blocks of :data:`WHITEN_BLOCK` tests
    (:mod:`analysis.identification.linalg.batch_lsq`): no LAPACK call per 6 x 6 matrix.
    """
    cov = np.asarray(cov, dtype=float)
    if cov.ndim == 3 and cov.shape[0] > TEST_BLOCK:
        # one large campaign: block by block into one output (whole-array temporaries of
        # 1e6 tests are ~6 x 0.3 GB, and their page faults cost more than the arithmetic)
        # ``out``: an array of cov's shape to overwrite (e.g. a whitening no longer needed)
        out = np.empty(cov.shape) if out is None or out.shape != cov.shape else out
        for s in range(0, cov.shape[0], TEST_BLOCK):
            out[s:s + TEST_BLOCK] = whitening(cov[s:s + TEST_BLOCK], None if measured is None
                                              else measured[s:s + TEST_BLOCK])
        return out
    n = cov.shape[-1]
    flat = cov.reshape(-1, n, n)
    meas = None if measured is None else np.broadcast_to(measured, cov.shape[:-1]).reshape(-1, n)
    res = np.empty(flat.shape)
    eye = np.eye(n)[:, :, None]
    for s in range(0, flat.shape[0], WHITEN_BLOCK):
        S = np.moveaxis(flat[s:s + WHITEN_BLOCK], 0, -1)  # (n, n, N) view, read column-wise
        mt = None if meas is None or meas[s:s + WHITEN_BLOCK].all() \
            else meas[s:s + WHITEN_BLOCK].T
        if mt is not None:  # unmeasured components: identity rows and columns
            S = np.where(mt[:, None] & mt[None], S, eye)
        X = batch_lsq.lower_inverse(batch_lsq.cholesky(S, check=True))
        if mt is not None:
            X *= mt[:, None]
        res[s:s + WHITEN_BLOCK] = np.moveaxis(X, -1, 0)
    return res.reshape(cov.shape)


def lower_inverse(L: np.ndarray) -> np.ndarray:
    """Inverse (..., n, n) of lower-triangular matrices L (..., n, n), batched.

    Forward substitution entry by entry over the whole batch at once
    (``Linv[i, j] = -sum_k L[i, k] Linv[k, j] / L[i, i]``, entry-major arrays,
    :func:`analysis.identification.linalg.batch_lsq.lower_inverse`): ~5x less CPU than an LU
    factorisation per 6 x 6 matrix (numpy.linalg.inv), backward stable like it.
    """
    n = L.shape[-1]
    E = np.moveaxis(L.reshape(-1, n, n), 0, -1)  # (n, n, N) view
    return np.moveaxis(batch_lsq.lower_inverse(E), -1, 0).reshape(L.shape)


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


#: rows per block of the tall (TSQR) path and tests per block of the blockwise statistics;
#: a block of 6000 x 7 doubles (0.3 MB) stays in cache during its Householder QR
#: (measured: 0.07 s for 6e5 x 7 rows against 0.22 s in blocks of 48000)
ROW_BLOCK = 6_000
TEST_BLOCK = 8_000
#: tests per block of :func:`whitening`: its working set (~10 arrays of 36 x 4096
#: doubles) stays in cache
WHITEN_BLOCK = 4_096
#: stacked systems with more rows than this are factorised blockwise (no Q, no A^+); read
#: in this module only (:func:`solve_blocks`, :class:`StackedRows`, :func:`qr_solve`,
#: :func:`scaled_condition`, :func:`weakest_column`): no estimator chooses by size
TALL_ROWS = 192_000


def blocks_of_tests(m: int, block: int | None = None) -> list[slice]:
    """Slices of ``block`` (default :data:`TEST_BLOCK`) consecutive tests covering 0..m."""
    block = TEST_BLOCK if block is None else block
    return [slice(s, s + block) for s in range(0, m, block)]


class TallR:
    """Triangular factor of a tall matrix fed by blocks of rows (TSQR).

    ``add(rows)`` reduces each :data:`ROW_BLOCK` rows to their R by Householder QR;
    the stacked R factors are reduced again (every 64 blocks and at ``r()``): the R
    of the whole matrix (up to the signs of its rows) with O(p^2) memory, instead of
    the r x p factor Q. The one place the blockwise factorisations of this package
    accumulate their rows.
    """

    def __init__(self, block: int | None = None) -> None:
        self.block = ROW_BLOCK if block is None else block
        self.Rs: list[np.ndarray] = []

    def add(self, rows: np.ndarray) -> None:
        """Append rows (r, q) of the matrix."""
        q = rows.shape[-1]
        for s in range(0, rows.shape[0], self.block):
            self.Rs.append(np.linalg.qr(rows[s:s + self.block], mode="r")[:q])
            if len(self.Rs) > 64:
                self.Rs = [np.linalg.qr(np.vstack(self.Rs), mode="r")[:q]]

    def r(self) -> np.ndarray:
        """R (q, q) of all the rows added (q = their number of columns)."""
        q = self.Rs[0].shape[-1]
        return np.linalg.qr(np.vstack(self.Rs), mode="r")[:q]


class StackedRows:
    """The rows of a stacked system fed block by block, kept as a matrix with its column
    norms and singular values (for :func:`scaled_condition` and :func:`weakest_column`):
    the stacked rows themselves up to :data:`TALL_ROWS` rows, else their R
    (:class:`TallR`, O(p^2) memory). ``rows``: how many the system has; ``tall``: take
    the R whatever the number (rows made when sliced: the system is not held).
    """

    def __init__(self, rows: int, tall: bool = False) -> None:
        self.acc = TallR() if tall or rows > TALL_ROWS else None
        self.parts: list[np.ndarray] = []

    def add(self, rows: np.ndarray) -> None:
        """Append rows (r, p) of the system."""
        if self.acc is not None:
            self.acc.add(rows)
        else:
            self.parts.append(rows)

    def matrix(self) -> np.ndarray:
        """The stacked rows (r, p), or their R (p, p)."""
        return self.acc.r() if self.acc is not None else np.concatenate(self.parts)


def tall_r(A: np.ndarray, d: np.ndarray | None = None, block: int | None = None,
           scale: np.ndarray | None = None) -> np.ndarray:
    """Triangular factor of [A | d] (r, p) -> (p(+1), p(+1)) by blocks of rows (TSQR).

    See :class:`TallR`. ``scale`` (p,): factorise [A / scale | d] instead (divided
    block by block: no scaled copy of A).
    """
    acc = TallR(block)
    step = acc.block * 8
    for s in range(0, A.shape[0], step):
        blk = A[s:s + step] if scale is None else A[s:s + step] / scale
        if d is not None:
            blk = np.column_stack([blk, d[s:s + step]])
        acc.add(blk)
    return acc.r()


def whitened_r(Linv: np.ndarray, A: np.ndarray, block: int = TEST_BLOCK) -> np.ndarray:
    """Triangular factor R (p, p) of the stacked whitened system Linv A, blockwise.

    ``Linv`` (m, 6, 6), ``A`` (m, 6, p). R^T R = A^T W A, so R has the column norms
    and singular values of the stacked Linv A (6m, p) (:func:`scaled_condition` of
    R equals that of Linv A) without forming it.
    """
    p = A.shape[-1]
    acc = TallR()
    for s in range(0, A.shape[0], block):
        acc.add((Linv[s:s + block] @ A[s:s + block]).reshape(-1, p))
    return acc.r()


def tall_solve(A: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x, (A^T A)^-1 of the least-squares A x ~ d for one tall A (r, p), blockwise.

    Same estimate as :func:`qr_solve` (Householder QR of the column-scaled A,
    no normal equations), without forming Q or A^+.
    """
    p = A.shape[-1]
    scale = column_scale(A)
    R = tall_r(A, d, scale=scale)
    Rinv = np.linalg.inv(R[:p, :p])
    x = (Rinv @ R[:p, p]) / scale
    cov_unit = (Rinv @ Rinv.T) / (scale[:, None] * scale[None, :])
    return x, cov_unit


def solve_blocks(A, r: np.ndarray, Linv=None, valid: np.ndarray | None = None,
                 Lr: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """x, (A^T W A)^-1 of the least squares ``Linv A x ~ Linv r`` for per-test blocks.

    ``A`` (..., m, 6, p) per-test design (zero rows where not measured; one campaign's
    may be made when sliced), ``r`` (..., m, 6) right-hand side (0 where not measured),
    ``Linv`` (..., m, 6, 6) per-test whitening (None: unweighted), W = Linv^T Linv;
    ``valid`` (...): campaigns of a batch whose system is defined (the others get I and
    a meaningless x); ``Lr``: the whitened right-hand side, if the caller has it.

    The one place the fits choose how to factorise their systems, by size: one campaign
    of more than :data:`TALL_ROWS` stacked rows (all valid) by the blockwise TSQR of
    :func:`whitened_lstsq` (no stacked (6m, p) copy), every other system by one QR of
    the stacked, column-scaled system (:func:`qr_solve`); the same estimate to rounding.
    """
    if A.ndim == 3 and A.shape[0] * 6 > TALL_ROWS and (valid is None or np.all(valid)):
        return whitened_lstsq(A, r, Linv)
    if Linv is not None:
        A = Linv @ A
        r = np.einsum("...ij,...j->...i", Linv, r) if Lr is None else Lr
    Aw = stack_matrix(A)
    if valid is not None and not np.all(valid):
        # the systems of invalid campaigns replaced by I (keeps their QR defined)
        Aw = np.where(valid[..., None, None], Aw, np.eye(*Aw.shape[-2:]))
    x, cov_unit, _ = qr_solve(Aw, stack_vector(r), with_pinv=False)
    return x, cov_unit


def whitened_lstsq(A: np.ndarray, r: np.ndarray, Linv: np.ndarray | None = None,
                   block: int = TEST_BLOCK) -> tuple[np.ndarray, np.ndarray]:
    """x, (A^T W A)^-1 of the least squares ``Linv A x ~ Linv r`` for one campaign.

    ``A`` (m, 6, p) per-test design (zero rows where not measured), ``r`` (m, 6)
    right-hand side (0 where not measured), ``Linv`` (m, 6, 6) per-test whitening
    (None: unweighted), W = Linv^T Linv; ``A`` and ``Linv`` may be made when sliced
    (:mod:`analysis.identification.streaming.per_test`). The one place the fits of this package form
    their (whitened) systems. The stacked (6m, p) whitened system is never held: the
    TSQR of [Linv A | Linv r] is built test block by test block in one pass
    (:class:`TallR`), and its R column-scaled afterwards (Householder QR's backward error
    is column-wise, so scaling before or after it gives the estimate of :func:`qr_solve`
    on the stacked system, to rounding).
    """
    m, p = A.shape[0], A.shape[-1]
    acc = TallR()
    for s in range(0, m, block):
        Ab, rb = A[s:s + block], r[s:s + block]
        if Linv is not None:
            Lb = Linv[s:s + block]
            Ab, rb = Lb @ Ab, np.einsum("mij,mj->mi", Lb, rb)
        acc.add(np.column_stack([Ab.reshape(-1, p), rb.reshape(-1)]))
    R = acc.r()
    norms = np.linalg.norm(R[:, :p], axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    Rinv = np.linalg.inv(R[:p, :p] / scale)
    x = (Rinv @ R[:p, p]) / scale
    cov_unit = (Rinv @ Rinv.T) / (scale[:, None] * scale[None, :])
    return x, cov_unit


