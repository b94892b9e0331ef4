"""The batched kernels of the large-import path equal their reference computations."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from analysis.identification import lsq
from analysis.kinetostatics.equilibrium import newton_deflection
from analysis.kinetostatics.small_linalg import solve_dominant_columns
from analysis.model.kinematics import rotation_vector


def _rotations(rng, n, angle_lo, angle_hi):
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    angle = rng.uniform(angle_lo, angle_hi, size=n)
    return np.stack([pin.exp3(a * t) for a, t in zip(axis, angle, strict=True)]), axis * angle[
        :, None]


@pytest.mark.parametrize("lo, hi", [(1e-9, 1e-6), (1e-4, 1e-2), (0.1, 2.4), (2.6, np.pi - 1e-6)])
def test_rotation_vector_equals_pinocchio_log3(lo, hi):
    """Batched log (atan2 form; near pi Pinocchio's own): equal to log3 to 1e-14 relative."""
    R, truth = _rotations(np.random.default_rng(3), 300, lo, hi)
    ref = np.stack([pin.log3(m) for m in R])
    got = rotation_vector(R)
    scale = np.linalg.norm(ref, axis=1)[:, None]
    np.testing.assert_allclose(got / scale, ref / scale, atol=2e-14)
    np.testing.assert_allclose(got / scale, truth / scale, atol=1e-12)
    assert rotation_vector(R.reshape(3, 100, 3, 3)).shape == (3, 100, 3)
    np.testing.assert_array_equal(rotation_vector(np.eye(3)), np.zeros(3))


def test_lower_inverse_equals_numpy_inverse():
    rng = np.random.default_rng(4)
    B = rng.normal(size=(500, 6, 6))
    L = np.linalg.cholesky(B @ np.swapaxes(B, -1, -2) + 0.1 * np.eye(6))
    got = lsq.lower_inverse(L)
    np.testing.assert_allclose(got, np.linalg.inv(L), rtol=1e-10, atol=1e-12 * np.abs(
        got).max())
    np.testing.assert_array_equal(np.triu(got, 1), 0.0)


def test_whitened_lstsq_equals_the_stacked_qr(monkeypatch):
    """Blockwise (97 tests, 50-row TSQR blocks) = one QR of the stacked whitened system."""
    rng = np.random.default_rng(5)
    m, p = 1000, 5
    A = rng.normal(size=(m, 6, p)) * np.array([1e-3, 1.0, 1e2, 1e-6, 10.0])
    A[::7, 2] = 0.0  # rows not measured
    L = np.tril(rng.normal(size=(m, 6, 6))) + 4 * np.eye(6)
    r = rng.normal(size=(m, 6))
    x0, cov0, _ = lsq.qr_solve((L @ A).reshape(-1, p), np.einsum("mij,mj->mi", L, r)
                               .reshape(-1))
    monkeypatch.setattr(lsq, "ROW_BLOCK", 50)
    x1, cov1 = lsq.whitened_lstsq(A, r, L, block=97)
    np.testing.assert_allclose(x1, x0, rtol=1e-10)
    np.testing.assert_allclose(cov1, cov0, rtol=1e-10)
    x2, cov2 = lsq.whitened_lstsq(A, r, None, block=97)  # unweighted
    x3, cov3, _ = lsq.qr_solve(A.reshape(-1, p), r.reshape(-1))
    np.testing.assert_allclose(x2, x3, rtol=1e-10)
    np.testing.assert_allclose(cov2, cov3, rtol=1e-10)


def test_solve_dominant_columns_equals_numpy_solve():
    rng = np.random.default_rng(6)
    M = np.eye(6) + 0.05 * rng.normal(size=(400, 6, 6))
    B = rng.normal(size=(400, 6, 6))
    M0, B0 = M.copy(), B.copy()
    np.testing.assert_allclose(solve_dominant_columns(M, B), np.linalg.solve(M, B),
                               rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(M, M0)  # inputs untouched
    np.testing.assert_array_equal(B, B0)
    M[7] = rng.normal(size=(6, 6))  # not dominant: the pivoting solver for the batch
    np.testing.assert_allclose(solve_dominant_columns(M, B), np.linalg.solve(M, B),
                               rtol=1e-10, atol=1e-12)


def test_newton_from_any_start_reaches_the_same_deflection(kr240, zone_poses, w_eff):
    """Warm and first-order starts converge to the cold start's deflection, to 1e-15 rad."""
    x = 1.0 / np.asarray(kr240.nominal_stiffness)
    cold, bad, last = newton_deflection(kr240, zone_poses, x, w_eff, 1e-15)
    assert not bad.any() and np.all(last <= 1e-15)
    for dq0 in (0.9 * cold, cold + 1e-6):
        warm, bad, last = newton_deflection(kr240, zone_poses, x, w_eff, 1e-15, dq0=dq0)
        assert not bad.any()
        np.testing.assert_allclose(warm, cold, rtol=0, atol=2e-15)
    keep: dict = {}
    dq, _, last = newton_deflection(kr240, zone_poses, x, w_eff, 1e-15, keep=keep)
    # the kept iterate is within the last step of the returned one
    assert np.max(np.abs(keep["dq"] - dq)) <= np.max(last) + 1e-18
