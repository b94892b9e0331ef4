"""Wrench errors-in-variables: S against an independent expectation, the corrected
solutions, and the bias they remove on simulated campaigns
(analysis.identification.corrections.wrench_eiv)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.corrections.wrench_eiv import corrected, wrench_eiv_matrix
from analysis.identification.estimators.fit_solvers import fit_exact, fit_linear
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.linalg.lsq import whitening
from analysis.identification.linalg.sandwich import sandwich
from analysis.identification.noise import NoiseModel
from analysis.identification.studies.robustness import sample_poses

from ._sim import simulate


def _spd(rng, n, scale):
    B = rng.normal(size=(n, 6, 6)) * scale[:, None]
    return B @ np.swapaxes(B, -1, -2) + np.eye(6) * scale**2


def test_S_is_the_expectation_of_A_of_the_wrench_noise():
    """S against E[A(e)^T W A(e)] computed from the model's own regressor (design_block)
    at the 12 symmetric sigma points e = +-sqrt(6) L_i u_k (Sigma_w = L L^T), which
    reproduce the mean and covariance of e and so the expectation of any quadratic form
    exactly."""
    rng = np.random.default_rng(1)
    m, cols = 4, [0, 1, 2, 4, 5]
    J = rng.normal(size=(m, 6, 6)) * np.array([1.0, 1, 1, 0.3, 0.3, 0.3])[:, None]
    scale = np.array([15.0, 15, 15, 2.5, 2.5, 2.5])
    cov_w = _spd(rng, m, scale)
    Linv = np.tril(rng.normal(size=(m, 6, 6))) + 3 * np.eye(6)
    Linv[1, 3] = 0.0  # a component not measured: its row of L^-1 is zero
    L = np.linalg.cholesky(cov_w)
    ref = np.zeros((len(cols), len(cols)))
    for i in range(m):
        W = Linv[i].T @ Linv[i]
        for k in range(6):
            for sgn in (1.0, -1.0):
                e = sgn * np.sqrt(6.0) * L[i][:, k]
                Ae = design_block(J[i], e)[:, cols]
                ref += Ae.T @ W @ Ae / 12.0
    S = wrench_eiv_matrix(J[..., cols], cov_w, Linv)
    np.testing.assert_allclose(S, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    # the same in blocks of one test, and summed per group
    np.testing.assert_allclose(wrench_eiv_matrix(J[..., cols], cov_w, Linv, block=1), S,
                               rtol=1e-13)
    per = wrench_eiv_matrix(J[..., cols], cov_w, Linv, group=np.array([0, 1, 0, 2]),
                            n_groups=3)
    np.testing.assert_allclose(per.sum(axis=0), S, rtol=1e-13)
    # a diagonal covariance given as its diagonal, OLS weights given as the measured mask
    diag = np.diagonal(cov_w, axis1=-2, axis2=-1)
    meas = rng.random((m, 6)) > 0.2
    np.testing.assert_allclose(
        wrench_eiv_matrix(J, diag, measured=meas),
        wrench_eiv_matrix(J, diag[..., None] * np.eye(6), meas[..., None] * np.eye(6)),
        rtol=1e-13)


def test_S_matches_the_sampled_expectation():
    """A sampled check (200k draws of the wrench noise) agrees within its own spread."""
    rng = np.random.default_rng(5)
    J = rng.normal(size=(2, 6, 6))
    cov_w = _spd(rng, 2, np.array([15.0, 15, 15, 2.5, 2.5, 2.5]))
    S = wrench_eiv_matrix(J, cov_w)
    e = np.einsum("mij,tmj->tmi", np.linalg.cholesky(cov_w), rng.normal(size=(200_000, 2, 6)))
    Ae = design_block(J, e)  # (t, m, 6, p)
    samples = np.einsum("tmrj,tmrk->tjk", Ae, Ae)
    mean, sem = samples.mean(axis=0), samples.std(axis=0) / np.sqrt(len(samples))
    assert np.all(np.abs(mean - S) < 5 * sem + 1e-12 * np.abs(S).max())


def test_corrected_solves_the_compensated_normal_equations():
    rng = np.random.default_rng(2)
    B = rng.normal(size=(30, 4))
    N = B.T @ B
    S = 0.01 * N + 0.001 * np.eye(4)
    b = rng.normal(size=4)
    x_c, bread_c = corrected(np.linalg.solve(N, b), np.linalg.inv(N), S)
    np.testing.assert_allclose((N - S) @ x_c, b, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(bread_c, np.linalg.inv(N - S), rtol=1e-11)


def _campaign(kr240, m, noise, seed, per_pose=10):
    """m tests, loads of 1-2.5 kN and 100-300 N m in random directions (the large-import
    benchmark's design), exact equilibrium plus the noise model's noise."""
    rng = np.random.default_rng(seed)
    q = np.repeat(sample_poses(kr240, m // per_pose, rng), per_pose, axis=0)
    f, mo = rng.normal(size=(m, 3)), rng.normal(size=(m, 3))
    f *= rng.uniform(1000, 2500, (m, 1)) / np.linalg.norm(f, axis=1, keepdims=True)
    mo *= rng.uniform(100, 300, (m, 1)) / np.linalg.norm(mo, axis=1, keepdims=True)
    return simulate(kr240, q, np.hstack([f, mo]), kr240.nominal_stiffness, noise, seed)


#: ten times the default F/T noise (156 N, 25 N m: 6-16 % of the loads), so that the
#: attenuation (~1e-2) shows at a few hundred tests instead of 1e5
LOUD_FT = NoiseModel(force_sigma=10 * NoiseModel().force_sigma,
                     moment_sigma=10 * NoiseModel().moment_sigma)


@pytest.mark.parametrize("method", ["wls", "exact"])
def test_correction_removes_the_attenuation_bias(kr240, method):
    """Monte-Carlo over 8 campaigns of 400 tests: the mean standardised error
    (x - x_true) / se of the uncorrected fit is well away from 0 (the bias the wrench
    noise causes, ~2.5 se per campaign for joints 1-3), the corrected one is not
    (the mean of 8 has a spread of 0.35)."""
    x_true = 1 / kr240.nominal_stiffness
    joints = tuple(range(6))
    z_raw, z_cor = [], []
    for seed in range(8):
        tests = _campaign(kr240, 400, LOUD_FT, seed)
        if method == "wls":
            f = fit_linear(kr240, tests, joints, LOUD_FT, weighted=True)
        else:
            f = fit_exact(kr240, tests, joints, LOUD_FT, start=x_true)
        se = np.sqrt(np.diag(sandwich(f.A, f.cov, f.bread, f.Linv)))
        z_cor.append((f.x - x_true) / se)
        z_raw.append((f.x - f.eiv_shift - x_true) / se)
    z_raw, z_cor = np.mean(z_raw, axis=0), np.mean(z_cor, axis=0)
    assert np.max(np.abs(z_raw)) > 2.0, z_raw
    assert np.all(z_raw[:3] < 0), z_raw  # attenuated compliances, k too high
    assert np.all(np.abs(z_cor) < 1.3), z_cor


def test_exact_fit_solves_the_corrected_estimating_equation(kr240):
    """At the corrected exact estimate, F^T W (d - f(x)) + S x = 0 up to the second order
    of the one Newton step (|shift| ~1e-2 x here): below 2 % of |S x|."""
    from analysis.identification.estimators.exact_model import model_displacement
    from analysis.model.kinematics import jacobian

    tests = _campaign(kr240, 200, LOUD_FT, 3)
    joints = tuple(range(6))
    f = fit_exact(kr240, tests, joints, LOUD_FT, start=1 / kr240.nominal_stiffness)
    W = np.swapaxes(f.Linv, -1, -2) @ f.Linv
    S = wrench_eiv_matrix(jacobian(kr240, tests.q), LOUD_FT.wrench_sigma_at(tests.w) ** 2,
                          f.Linv)
    model, F = model_displacement(kr240, tests.q, f.x, tests.w)
    score = np.einsum("mrp,mrs,ms->p", F, W, tests.d - model)
    assert np.linalg.norm(S @ f.x) > 1e3 * np.linalg.norm(score + S @ f.x)
    # ...while the uncorrected minimum leaves the whole of S x
    raw = f.x - f.eiv_shift
    model0, F0 = model_displacement(kr240, tests.q, raw, tests.w)
    score0 = np.einsum("mrp,mrs,ms->p", F0, W, tests.d - model0)
    assert np.linalg.norm(score0 + S @ raw) > 0.5 * np.linalg.norm(S @ raw)


def test_small_campaigns_are_moved_by_a_tiny_fraction_of_their_standard_error(
        kr240, zone_poses, w_eff):
    """At 5-50 tests with the default F/T figures the correction is a few hundredths of
    a standard error (it grows as sqrt(m): at most 0.02, 0.025, 0.05 se here)."""
    noise = NoiseModel()
    for m in (5, 12, 50):
        q = zone_poses[np.arange(m) % len(zone_poses)]
        tests = simulate(kr240, q, w_eff, kr240.nominal_stiffness, noise, seed=m)
        f = fit_exact(kr240, tests, tuple(range(6)), noise, start=1 / kr240.nominal_stiffness)
        se = np.sqrt(np.diag(sandwich(f.A, f.cov, f.bread, f.Linv)))
        assert np.max(np.abs(f.eiv_shift) / se) < 0.1 * np.sqrt(m / 50)
        assert np.max(np.abs(f.eiv_shift) / se) > 0  # applied all the same
    # the whitening used is that of the fit (the weights are W = Sigma^-1)
    np.testing.assert_allclose(f.Linv, whitening(f.cov, tests.measured))


def test_the_correction_is_a_warning_only_where_it_moves_k(kr240, zone_poses, w_eff):
    """Always in results.json; among the warnings only from 0.1 se on: a 15-test campaign
    with the default F/T figures (~1e-2 se) has none, 400 tests with ten times the noise
    (several se) have it."""
    from analysis.identification.estimate import identify
    from analysis.identification.intervals import EIV_WARN_SE

    q = zone_poses[np.arange(15) % len(zone_poses)]
    small = identify(kr240, simulate(kr240, q, w_eff, kr240.nominal_stiffness, NoiseModel(),
                                     seed=3), validate=False)
    assert small.wrench_eiv["max_abs_shift_in_se"] < EIV_WARN_SE
    assert not any("errors-in-variables" in w for w in small.warnings)
    loud = identify(kr240, _campaign(kr240, 400, LOUD_FT, seed=4), noise=LOUD_FT,
                    validate=False)
    assert loud.wrench_eiv["max_abs_shift_in_se"] > 1.0
    assert any("errors-in-variables corrected" in w for w in loud.warnings)
