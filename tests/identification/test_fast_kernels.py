"""The batched kernels of the large-import path equal their reference computations."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from analysis.identification.linalg import lsq
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


def _spd(rng, shape, spread=1e3):
    """Covariances (*shape, 6, 6) with eigenvalues over ``spread`` (condition ~spread^2)."""
    B = rng.normal(size=(*shape, 6, 6)) * np.geomspace(1.0, 1.0 / spread, 6)
    return B @ np.swapaxes(B, -1, -2) + 1e-8 * np.eye(6)


def _whitening_reference(cov, measured):
    """np.linalg.inv of np.linalg.cholesky, one test at a time, unmeasured decoupled."""
    out = np.zeros(cov.shape)
    for idx in np.ndindex(cov.shape[:-2]):
        m = measured[idx]
        c = np.where(np.outer(m, m), cov[idx], np.eye(6))
        out[idx] = np.linalg.inv(np.linalg.cholesky(c)) * m[:, None]
    return out


@pytest.mark.parametrize("shape", [(700,), (3, 50), ()])
def test_whitening_equals_inverse_of_numpy_cholesky(shape, monkeypatch):
    """Entry-major Cholesky + inverse (blocks of 97 tests) = inv(cholesky) per test, with
    unmeasured components decoupled and their rows zeroed. Both are backward stable:
    they differ by ~eps cond(L)^2 of each matrix's scale (cond(L) up to ~4e4 here), and
    L^-1 Sigma L^-T = I on the measured block to ~eps cond(Sigma)."""
    monkeypatch.setattr(lsq, "WHITEN_BLOCK", 97)
    rng = np.random.default_rng(11)
    cov = _spd(rng, shape)
    measured = rng.random((*shape, 6)) > 0.2
    if shape:
        measured.reshape(-1, 6)[::5] = True  # blocks with every component measured too
    for mask in (measured, None):
        m = np.ones((*shape, 6), dtype=bool) if mask is None else mask
        got = lsq.whitening(cov, mask)
        ref = _whitening_reference(cov, m)
        c = np.where(m[..., :, None] & m[..., None, :], cov, np.eye(6))
        cond_L = np.sqrt(np.linalg.cond(c))
        scale = np.abs(ref).max(axis=(-2, -1))
        assert np.all(np.abs(got - ref).max(axis=(-2, -1)) <= 1e-15 * cond_L**2 * scale)
        eye = np.eye(6) * (m[..., :, None] & m[..., None, :])
        resid = np.abs(got @ c @ np.swapaxes(got, -1, -2) - eye).max(axis=(-2, -1))
        assert np.all(resid <= 1e-15 * cond_L**2)
        np.testing.assert_array_equal(got[~m], 0.0)
        np.testing.assert_array_equal(np.triu(got, 1), 0.0)


def test_whitening_refuses_what_numpy_cholesky_refuses():
    """Not positive definite: LinAlgError, as numpy.linalg.cholesky; NaN propagates."""
    rng = np.random.default_rng(12)
    cov = _spd(rng, (40,))
    bad = cov.copy()
    bad[17, 4, 4] = -1.0
    with pytest.raises(np.linalg.LinAlgError):
        np.linalg.cholesky(bad)
    with pytest.raises(np.linalg.LinAlgError):
        lsq.whitening(bad)
    measured = np.ones((40, 6), dtype=bool)
    measured[17, 4] = False  # the bad component decoupled: accepted
    assert np.isfinite(lsq.whitening(bad, measured)).all()
    nan = cov.copy()
    nan[3, 0, 0] = np.nan
    got = lsq.whitening(nan)
    assert np.isnan(got[3]).any() and np.isfinite(np.delete(got, 3, axis=0)).all()


def test_left_jacobian_inverse_equals_inverse_of_closed_form():
    """J_l^-1(phi) = inv(I + (1 - cos t)/t^2 K + (t - sin t)/t^3 K^2), K = [phi]x, from
    1e-7 rad (below the 1e-4 rad switch to the series) to 2 rad."""
    from analysis.identification.estimators.exact_model import so3_left_jacobian_inverse

    rng = np.random.default_rng(13)
    phi = rng.normal(size=(200, 3))
    phi *= (np.geomspace(1e-7, 2.0, 200) / np.linalg.norm(phi, axis=1))[:, None]
    t = np.linalg.norm(phi, axis=1)[:, None, None]
    K = np.zeros((200, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -phi[:, 2], phi[:, 1], -phi[:, 0]
    K -= np.swapaxes(K, -1, -2)
    np.testing.assert_allclose(K @ [1.0, 2.0, 3.0], np.cross(phi, [1.0, 2.0, 3.0]), atol=1e-15)
    big = t[:, 0, 0] > 1e-3  # the closed form of J_l itself loses digits at small angles
    Jl = np.eye(3) + (1 - np.cos(t)) / t**2 * K + (t - np.sin(t)) / t**3 * (K @ K)
    got = so3_left_jacobian_inverse(phi)
    np.testing.assert_allclose(got[big], np.linalg.inv(Jl[big]), rtol=0, atol=1e-13)
    # small angles: J_l^-1 = I - K/2 + K^2/12 + O(t^4)
    series = np.eye(3) - K / 2 + (K @ K) / 12
    np.testing.assert_allclose(got[~big], series[~big], rtol=0, atol=1e-13)
    assert so3_left_jacobian_inverse(phi.reshape(4, 50, 3)).shape == (4, 50, 3, 3)


def test_exact_model_equals_an_independent_composition(kr240, zone_poses, w_eff):
    """Screw, deflection and derivative of the exact model = Pinocchio's pose and
    Jacobian at q + dq composed with numpy (K_C, a 6 x 6 solve, J_l^-1); cold start,
    warm start and cached unloaded poses give the same numbers."""
    from analysis.identification.estimators.exact_model import (
        model_displacement_state,
        so3_left_jacobian_inverse,
    )
    from analysis.kinetostatics.stiffness import complementary_stiffness_from_jacobian
    from analysis.model.kinematics import pin_jacobian, pin_tool_pose, pose_difference

    rng = np.random.default_rng(14)
    q = np.repeat(zone_poses, 20, axis=0)
    w = w_eff * rng.uniform(-1.0, 1.0, (len(q), 1))
    x = 1.0 / np.asarray(kr240.nominal_stiffness) * rng.uniform(0.5, 2.0, 6)
    unloaded: dict = {}
    f, F, ok, dq = model_displacement_state(kr240, q, x, w, True, unloaded=unloaded)
    assert ok.all() and np.abs(dq).max() > 1e-3
    for k in range(0, len(q), 7):
        qk = q[k] + dq[k]
        J = pin_jacobian(kr240, qk)
        np.testing.assert_allclose(dq[k], x * (J.T @ w[k]), rtol=0, atol=2e-15)
        screw = pose_difference(pin_tool_pose(kr240, q[k]), pin_tool_pose(kr240, qk))
        np.testing.assert_allclose(f[k], screw, rtol=0, atol=5e-15)
        M = np.eye(6) - x[:, None] * complementary_stiffness_from_jacobian(J, w[k])
        D = np.vstack([J[:3], so3_left_jacobian_inverse(screw[3:]) @ J[3:]])
        ref = D @ np.linalg.solve(M, np.diag(J.T @ w[k]))
        np.testing.assert_allclose(F[k], ref, rtol=0, atol=1e-12 * np.abs(ref).max())
    for args in ((dq,), (dq * 0.97,), (dq, dict(unloaded))):
        f2, F2, ok2, dq2 = model_displacement_state(kr240, q, x, w, True, *args)
        np.testing.assert_allclose(dq2, dq, rtol=0, atol=2e-17)
        # FK rounding: a few ulps of the tool position (~2.5 m)
        np.testing.assert_allclose(f2, f, rtol=0, atol=2e-15)
        np.testing.assert_allclose(F2, F, rtol=1e-12, atol=1e-12 * np.abs(F).max())
    # a pose that buckles the model: not ok, zeros; the others unchanged (their state is
    # then recomputed at the solution instead of kept from Newton's last iterate)
    w2 = w.copy()
    w2[5] *= 1e4
    f3, F3, ok3, dq3 = model_displacement_state(kr240, q, x, w2, True, dq)
    assert not ok3[5] and np.delete(ok3, 5).all()
    assert not f3[5].any() and not F3[5].any() and not dq3[5].any()
    keep = np.arange(len(q)) != 5
    np.testing.assert_allclose(dq3[keep], dq[keep], rtol=0, atol=2e-17)
    np.testing.assert_allclose(f3[keep], f[keep], rtol=0, atol=2e-15)
    np.testing.assert_allclose(F3[keep], F[keep], rtol=1e-12, atol=1e-12 * np.abs(F).max())


def test_cold_start_keeps_every_solution_either_start_finds(kr240):
    """Loads near buckling (deflections up to ~1 rad): Newton from zero overshoots at some
    poses where it converges from the first-order deflection, and the reverse; the exact
    model (from zero, then from x J(q)^T w) solves exactly the poses either start solves,
    to the same deflection."""
    from analysis.identification.estimators.exact_model import model_displacement_state
    from analysis.model.kinematics import jacobian

    rng = np.random.default_rng(1)
    q = rng.uniform(kr240.lower, kr240.upper, (400, 6)) * 0.6
    w = rng.normal(size=(400, 6)) * np.r_[[3000.0] * 3, [300.0] * 3] * 25
    x = 1 / np.asarray(kr240.nominal_stiffness)
    d1 = x * np.einsum("nji,nj->ni", jacobian(kr240, q), w)
    dz, bz, lz = newton_deflection(kr240, q, x, w, 1e-15, max_deflection=1.0)
    d1s, b1, l1 = newton_deflection(kr240, q, x, w, 1e-15, dq0=d1, max_deflection=1.0)
    okz, ok1 = ~bz & (lz <= 1e-15), ~b1 & (l1 <= 1e-15)
    assert (ok1 & ~okz).sum() > 10 and 0 < (~ok1).sum()  # the two starts differ here
    _, _, ok, dq = model_displacement_state(kr240, q, x, w, False)
    np.testing.assert_array_equal(ok, okz | ok1)
    np.testing.assert_allclose(dq[ok1], d1s[ok1], rtol=0, atol=1e-14)
