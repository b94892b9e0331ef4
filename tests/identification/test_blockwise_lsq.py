"""Blockwise least squares and statistics equal the dense reference computations."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.estimators.fit_solvers import _full, fit
from analysis.identification.linalg import lsq
from analysis.identification.linalg.lsq import (
    block_diag_apply,
    qr_solve,
    scaled_condition,
    stack_matrix,
    stack_vector,
    tall_r,
    tall_solve,
    weakest_column,
)
from analysis.identification.linalg.sandwich import (
    per_test_diagonal,
    residual_variance_blocks,
    sandwich,
    sandwich_and_residual_variance,
)
from analysis.identification.noise import NoiseModel
from analysis.identification.uncertainty import residual_variance
from analysis.model.kinematics import jacobian

from ._sim import simulate


def test_tall_solve_equals_qr_solve_across_blocks():
    """Rows in 7 blocks of 50 (+ a short one): same x and (A^T A)^-1 as one QR.

    Both are backward stable; they differ by rounding, ~1e-10 relative here."""
    rng = np.random.default_rng(0)
    A = rng.normal(size=(353, 5)) * np.array([1e-6, 1.0, 1e3, 2.0, 1e-2])
    d = A @ rng.normal(size=5) + 1e-3 * rng.normal(size=353)
    x0, cov0, _ = qr_solve(A, d)
    scale = lsq.column_scale(A)
    R = tall_r(A / scale, d, block=50)
    Rinv = np.linalg.inv(R[:5, :5])
    x1 = Rinv @ R[:5, 5] / scale
    cov1 = Rinv @ Rinv.T / np.outer(scale, scale)
    np.testing.assert_allclose(x1, x0, rtol=1e-8)
    np.testing.assert_allclose(cov1, cov0, rtol=1e-8)
    x2, cov2 = tall_solve(A, d)  # default blocks (one block here)
    np.testing.assert_allclose(x2, x0, rtol=1e-8)
    np.testing.assert_allclose(cov2, cov0, rtol=1e-8)


def test_tall_condition_and_weakest_column_equal_the_dense_ones(monkeypatch):
    rng = np.random.default_rng(1)
    A = rng.normal(size=(400, 4))
    A[:, 3] = A[:, 0] + 1e-4 * rng.normal(size=400)  # near-dependent pair
    cond, weak = float(scaled_condition(A)), weakest_column(A)
    monkeypatch.setattr(lsq, "TALL_ROWS", 100)
    monkeypatch.setattr(lsq, "ROW_BLOCK", 64)
    assert float(scaled_condition(A)) == pytest.approx(cond, rel=1e-8)
    assert weakest_column(A) == weak
    x0, cov0, _ = qr_solve(A, A[:, 1])
    x1, cov1, pinv = qr_solve(A, A[:, 1], with_pinv=False)  # tall path now
    assert pinv is None
    np.testing.assert_allclose(x1, x0, atol=1e-12)
    np.testing.assert_allclose(cov1, cov0, rtol=1e-8)


def _whitened_blocks(rng, shape, p):
    """Per-test blocks A (..., m, 6, p), r (..., m, 6) and a lower-triangular Linv."""
    A = rng.normal(size=(*shape, 6, p)) * np.array([1e-6, 1.0, 1e3, 2.0][:p])
    r = rng.normal(size=(*shape, 6))
    Linv = np.tril(rng.normal(size=(*shape, 6, 6))) + 3 * np.eye(6)
    return A, r, Linv


def test_solve_blocks_chooses_the_factorisation_by_size_with_the_same_estimate(
        monkeypatch):
    """The one place the fits' factorisation is chosen: one QR of the stacked whitened
    system up to TALL_ROWS rows, the blockwise TSQR beyond; both equal the dense normal
    equations' solution (an independent formula) to 1e-9 relative."""
    rng = np.random.default_rng(7)
    A, r, Linv = _whitened_blocks(rng, (120,), 4)
    LA, Lr = (Linv @ A).reshape(-1, 4), np.einsum("mij,mj->mi", Linv, r).reshape(-1)
    cov_ref = np.linalg.inv(LA.T @ LA)
    x_ref = cov_ref @ LA.T @ Lr
    called = []
    real = lsq.whitened_lstsq
    monkeypatch.setattr(lsq, "whitened_lstsq", lambda *a, **k: called.append(1) or real(*a))
    small = lsq.solve_blocks(A, r, Linv)
    assert called == []  # 720 rows: stacked
    monkeypatch.setattr(lsq, "TALL_ROWS", 600)
    tall = lsq.solve_blocks(A, r, Linv)
    assert called == [1]
    for x, cov in (small, tall):
        np.testing.assert_allclose(x, x_ref, rtol=1e-9)
        np.testing.assert_allclose(cov, cov_ref, rtol=1e-9)
    # unweighted: the plain least squares
    x_ols, _ = lsq.solve_blocks(A, r)
    np.testing.assert_allclose(x_ols, np.linalg.lstsq(A.reshape(-1, 4), r.reshape(-1),
                                                      rcond=None)[0], rtol=1e-9)


def test_solve_blocks_of_a_batch_with_an_invalid_campaign():
    """A batch is solved stacked; an invalid campaign's system is replaced by I and the
    valid campaigns get their own solutions (each equal to its solve alone, 1e-12)."""
    rng = np.random.default_rng(8)
    A, r, Linv = _whitened_blocks(rng, (3, 20), 3)
    A[1] = np.nan  # a campaign whose model could not be evaluated
    valid = np.array([True, False, True])
    x, cov = lsq.solve_blocks(A, r, Linv, valid)
    assert np.all(np.isfinite(x[[0, 2]])) and np.all(np.isfinite(cov[[0, 2]]))
    for i in (0, 2):
        xi, covi = lsq.solve_blocks(A[i], r[i], Linv[i])
        np.testing.assert_allclose(x[i], xi, rtol=1e-12)
        np.testing.assert_allclose(cov[i], covi, rtol=1e-12)


def test_stacked_rows_keep_the_singular_values_small_or_tall(monkeypatch):
    rng = np.random.default_rng(9)
    blocks = [rng.normal(size=(30, 3)) for _ in range(5)]
    dense = np.concatenate(blocks)
    acc = lsq.StackedRows(150)
    for b in blocks:
        acc.add(b)
    np.testing.assert_array_equal(acc.matrix(), dense)  # small: the rows themselves
    monkeypatch.setattr(lsq, "TALL_ROWS", 100)
    for tall in (lsq.StackedRows(150), lsq.StackedRows(10, tall=True)):
        for b in blocks:
            tall.add(b)
        R = tall.matrix()
        assert R.shape == (3, 3)
        np.testing.assert_allclose(np.linalg.svd(R, compute_uv=False),
                                   np.linalg.svd(dense, compute_uv=False), rtol=1e-12)
        assert float(scaled_condition(R)) == pytest.approx(float(scaled_condition(dense)),
                                                           rel=1e-12)


@pytest.mark.parametrize("method", ["ols", "wls", "exact"])
def test_sandwich_and_residual_variance_equal_the_hat_matrix_forms(kr240, zone_poses, w_eff,
                                                                   method):
    """G Sigma G^T and diag Var(r) from the dense p x 6m G equal the blockwise sums
    (blocks of 3 tests, so block edges are crossed), to 1e-10 relative."""
    tests = simulate(kr240, zone_poses[:10], w_eff, kr240.nominal_stiffness, NoiseModel(),
                     seed=2)
    joints = tuple(range(6))
    f = fit(kr240, tests, joints, NoiseModel(), method)
    G = f.G
    GS = block_diag_apply(G, f.cov)
    cov_dense = GS @ G.T
    var_dense = residual_variance(stack_matrix(f.A), GS, stack_vector(
        np.diagonal(f.cov, axis1=-2, axis2=-1)), cov_dense).reshape(-1, 6)
    cov_block = sandwich(f.A, f.cov, f.bread, f.Linv, block=3)
    var_block = residual_variance_blocks(f.A, f.cov, f.bread, cov_block, f.Linv, block=3)
    np.testing.assert_allclose(cov_block, cov_dense, rtol=1e-10, atol=1e-12 * np.abs(
        cov_dense).max())
    np.testing.assert_allclose(var_block, var_dense, rtol=1e-9, atol=1e-12 * var_dense.max())
    # one pass over Sigma: the same numbers as the two passes, from the covariances made
    # block by block when sliced (PerTestCovariance), blocks of 3 tests
    from analysis.identification.streaming.covariances import PerTestCovariance

    cov_fused, var_fused = sandwich_and_residual_variance(f.A, f.cov, f.bread, f.Linv, block=3)
    np.testing.assert_array_equal(cov_fused, cov_block)
    np.testing.assert_array_equal(var_fused, var_block)
    if method == "ols":  # OLS evaluates its covariances at its final x
        lazy = PerTestCovariance(NoiseModel(), jacobian(kr240, tests.q), _full(f.x, joints),
                                 tests.measured, tests.w)
        np.testing.assert_allclose(np.asarray(lazy), f.cov, rtol=1e-12, atol=0)
        np.testing.assert_allclose(per_test_diagonal(lazy, block=3),
                                   np.diagonal(f.cov, axis1=-2, axis2=-1), rtol=1e-12, atol=0)
        cov_lazy, var_lazy = sandwich_and_residual_variance(f.A, lazy, f.bread, f.Linv, block=3)
        np.testing.assert_allclose(cov_lazy, cov_block, rtol=1e-12)
        np.testing.assert_allclose(var_lazy, var_block, rtol=1e-12)
    # the blockwise operator equals the dense G (blocks of 4 tests)
    v = np.random.default_rng(5).normal(size=G.shape[1])
    est = f.estimator
    est = type(est)(est.bread, est.A, est.Linv, block=4)
    np.testing.assert_allclose(est @ v, G @ v, rtol=1e-10, atol=1e-12 * np.abs(G @ v).max())
    # the estimator reproduces the estimate: x = G d (linear fits)
    if method != "exact":
        np.testing.assert_allclose(G @ stack_vector(tests.d), f.x, rtol=1e-10)


def test_whitened_r_has_the_condition_and_gram_of_the_stacked_system():
    rng = np.random.default_rng(11)
    m = 1000
    A = rng.normal(size=(m, 6, 5)) * np.array([1e-3, 1.0, 1e2, 1e-6, 10.0])
    L = np.tril(rng.normal(size=(m, 6, 6))) + 4 * np.eye(6)
    R = lsq.whitened_r(L, A, block=97)  # several blocks and a ragged last one
    Aw = (L @ A).reshape(-1, 5)
    np.testing.assert_allclose(R.T @ R, Aw.T @ Aw, rtol=1e-12)
    assert lsq.scaled_condition(R) == pytest.approx(lsq.scaled_condition(Aw), rel=1e-10)
    assert np.allclose(np.triu(R), R)
