"""Per-fold sums of a whitened system, made a block of tests at a time.

The leave-one-pose-out validation of a large campaign needs, per fold, the sums of the
whitened rows (their Gram matrix, score and the fold's part of the wrench
errors-in-variables S); a streamed exact fit makes them in the pass that forms its
final system (:class:`FinalPassSums`), so that the validation needs no pass of its own.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel


class FoldSums:
    """Sums per fold of the rows of a whitened system, ``Z`` (b, 6, p) and ``r`` (b, 6) a
    block of tests at a time: ``gram`` = sum Z^T Z and ``held`` the folds' part of the
    wrench errors-in-variables S (:mod:`analysis.identification.corrections.wrench_eiv`),
    both as upper triangles (P, p (p + 1) / 2) (:class:`PackedSym`), and ``score``
    (P, p) = sum Z^T r."""

    def __init__(self, n_folds: int, cols: list[int]) -> None:
        p = len(cols)
        self.cols, self.iu = list(cols), np.triu_indices(p)
        n = len(self.iu[0])
        self.gram, self.score, self.held = (np.zeros((n_folds, n)), np.zeros((n_folds, p)),
                                            np.zeros((n_folds, n)))

    def add(self, fold, J, Linv, measured, wrench_var, Z, r) -> np.ndarray:
        """Add the tests of one block: their folds (b,), J (b, 6, 6), whitening Linv
        (b, 6, 6) or None (OLS), measured (b, 6), wrench variances (b, 6), Z and r.
        Returns the block's S per fold present (k, p, p)."""
        from analysis.identification.corrections.wrench_eiv import wrench_eiv_matrix

        folds, local = np.unique(fold, return_inverse=True)
        k, iu = len(folds), self.iu
        held = wrench_eiv_matrix(J, wrench_var, Linv, measured, group=local, n_groups=k,
                                 cols=self.cols)
        self.held[folds] += held[:, iu[0], iu[1]]
        # per-fold sums by bincount over the folds present in the block, one entry at a
        # time (numpy's add.at is ~10x slower)
        ZZ = np.einsum("mri,mrj->mij", Z, Z)[:, iu[0], iu[1]]
        Zr = np.einsum("mri,mr->mi", Z, r)
        self.gram[folds] += np.stack([np.bincount(local, ZZ[:, e], k)
                                      for e in range(ZZ.shape[1])], axis=-1)
        self.score[folds] += np.stack([np.bincount(local, Zr[:, e], k)
                                       for e in range(Zr.shape[1])], axis=-1)
        return held


class FinalPassSums:
    """Sums over the tests made in the pass that forms a streamed exact fit's final system.

    Called by :func:`~analysis.identification.estimators.gauss_newton.gauss_newton` with each block
    of tests (slice, J (b, 6, 6), whitening Linv (b, 6, 6), whitened model Jacobian
    Linv F (b, 6, p) and residual Linv r (b, 6)) at the solution and its weights. Holds
    the wrench errors-in-variables ``S`` (p, p) and, with the tests' folds ``fold`` (m,)
    ints < ``n_folds`` (pose groups), ``folds``: the :class:`FoldSums` of Linv F and
    Linv r -- what leave-one-pose-out needs, without a pass of its own.
    """

    def __init__(self, tests: TestArrays, joints, noise: NoiseModel,
                 fold: np.ndarray | None = None, n_folds: int = 0) -> None:
        self.tests, self.cols, self.noise = tests, list(joints), noise
        self.fold, self.n_folds = fold, n_folds
        self.S = np.zeros((len(self.cols), len(self.cols)))
        self.folds = None  # made at the first block (not held through the iterations)

    def __call__(self, sl, J, Linv, LF, Lr) -> None:
        from analysis.identification.corrections.wrench_eiv import wrench_eiv_matrix

        t = self.tests
        sig2 = self.noise.wrench_sigma_at(t.w[sl]) ** 2
        if self.fold is None:
            self.S += wrench_eiv_matrix(J, sig2, Linv, t.measured[sl], cols=self.cols)
            return
        if self.folds is None:
            self.folds = FoldSums(self.n_folds, self.cols)
        self.S += self.folds.add(self.fold[sl], J, Linv, t.measured[sl], sig2, LF,
                                 Lr).sum(axis=0)


class PackedSym:
    """Symmetric p x p matrices per fold stored as their upper triangles (P, p (p + 1) / 2):
    ``obj[h]`` / :meth:`chunk` the full matrices of folds ``h``, :meth:`total` their sum."""

    def __init__(self, packed: np.ndarray, p: int) -> None:
        self.packed, self.p = packed, p
        self.iu = np.triu_indices(p)

    def chunk(self, h) -> np.ndarray:
        out = np.empty((len(h), self.p, self.p))
        vals = self.packed[h]
        out[:, self.iu[0], self.iu[1]] = vals
        out[:, self.iu[1], self.iu[0]] = vals
        return out

    __getitem__ = chunk

    def total(self) -> np.ndarray:
        """The sum over every fold (p, p)."""
        out = np.empty((self.p, self.p))
        vals = self.packed.sum(axis=0)
        out[self.iu[0], self.iu[1]] = vals
        out[self.iu[1], self.iu[0]] = vals
        return out
