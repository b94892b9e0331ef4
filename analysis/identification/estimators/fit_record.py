"""One fit's output on per-test blocks (internal to the estimators and the stages after
them), and its linear(ised) estimator x = G d kept in factored form."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FactoredEstimator:
    """x = G d with G = bread A^T W (W = Linv^T Linv per test, identity if Linv is None),
    applied to stacked vectors (6m,) block by block (never forming the p x 6m G)."""

    bread: np.ndarray
    A: np.ndarray
    Linv: np.ndarray | None = None
    block: int = 8_000

    @property
    def shape(self) -> tuple[int, int]:
        return (self.bread.shape[0], 6 * self.A.shape[0])

    def __matmul__(self, v: np.ndarray) -> np.ndarray:
        v = np.asarray(v, dtype=float).reshape(self.A.shape[0], 6)
        acc = np.zeros(self.A.shape[-1])
        for s in range(0, self.A.shape[0], self.block):
            vb = v[s:s + self.block]
            if self.Linv is not None:
                Lb = self.Linv[s:s + self.block]
                vb = np.einsum("mji,mj->mi", Lb, np.einsum("mij,mj->mi", Lb, vb))
            acc += np.einsum("mrp,mr->p", self.A[s:s + self.block], vb)
        return self.bread @ acc


@dataclass(frozen=True)
class Fit:
    """One estimator's output on per-test blocks (internal); a frozen record (the stages
    after the fit make new ones with :func:`dataclasses.replace`).

    x (p,) compliances (rad/(N m)); A (m, 6, p) model (or its Jacobian) per
    test; cov (m, 6, 6) residual covariance per test; predicted (m, 6) model
    displacement (m, rad). The linear(ised) estimator x = G d is kept in
    factored form, G = bread A^T W with W = Linv^T Linv per test (identity
    when ``Linv`` is None, OLS) and bread (p, p) = (A^T W A)^-1: memory
    linear in the number of tests (:mod:`analysis.identification.linalg.sandwich` computes
    its covariance and residual variances blockwise). ``deflection`` (m, 6): the
    exact fit's joint deflections at x (rad), None for the linear fits. ``eiv_shift``
    (p,): how far the wrench errors-in-variables correction moved x
    (:mod:`analysis.identification.corrections.wrench_eiv`; None when not applied); ``bread`` is
    then the
    corrected (A^T W A - S)^-1. ``R`` (p + 1, p + 1): for a fit of one large campaign
    whose A and Linv are made when sliced (:mod:`analysis.identification.streaming.per_test`), the
    triangular factor of its final whitened system [Linv A | Linv r] at x - eiv_shift,
    else None. ``predicted_shifted`` False: ``predicted`` is still at x - eiv_shift (the
    caller moves it by A eiv_shift,
    :func:`analysis.identification.estimators.fit_solvers.fit_exact`).
    """

    x: np.ndarray
    A: np.ndarray
    cov: np.ndarray
    predicted: np.ndarray
    iterations: int
    bread: np.ndarray
    Linv: np.ndarray | None = None
    deflection: np.ndarray | None = None
    eiv_shift: np.ndarray | None = None
    R: np.ndarray | None = None
    predicted_shifted: bool = True

    @property
    def estimator(self) -> FactoredEstimator:
        """G as an operator: ``fit.estimator @ v`` = G v for stacked v (6m,), blockwise."""
        return FactoredEstimator(self.bread, self.A, self.Linv)

    @property
    def G(self) -> np.ndarray:
        """The dense estimator matrix (p, 6m); for small campaigns and tests only."""
        WA = self.A if self.Linv is None else np.swapaxes(self.Linv, -1, -2) @ (
            self.Linv @ self.A)
        return self.bread @ WA.reshape(-1, WA.shape[-1]).T
