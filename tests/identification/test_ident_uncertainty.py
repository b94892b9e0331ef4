"""Uncertainty: spread vs covariance, interval coverage, intervals of k, outliers.

The Monte-Carlo checks run the exact fit batched over 1000 seeded campaigns
(:func:`analysis.identification.estimators.gauss_newton.gauss_newton`), with data from the nonlinear
equilibrium and the noise model's normal noise on displacement, wrench and
joint angles; identify() is checked to give the same covariance on one of
them.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from analysis.identification.corrections.wrench_eiv import corrected, wrench_eiv_matrix
from analysis.identification.estimate import identify
from analysis.identification.estimators.gauss_newton import gauss_newton
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import qr_solve, whitening
from analysis.identification.noise import NoiseModel
from analysis.identification.studies.robustness import build_pool
from analysis.identification.uncertainty import critical_value, stiffness_interval
from analysis.model.kinematics import jacobian

from ._sim import simulate

TRIALS = 1000


def _campaigns(robot, q, w_true, k, noise, rng):
    """Noisy (q, w, d) (T, m, 6) of campaigns at poses q (T, m, 6)."""
    from analysis.kinetostatics.equilibrium import displacement_screw

    d = displacement_screw(robot, q, k, np.broadcast_to(w_true, q.shape))
    d = d + rng.normal(size=d.shape) * noise.displacement_sigma
    w = w_true + rng.normal(size=q.shape) * noise.wrench_sigma
    qm = q + rng.normal(size=q.shape) * noise.joint_sigma
    return qm, w, d


def _fit(robot, q, w, d, noise):
    T, m = q.shape[:2]
    A = design_block(jacobian(robot, q), w).reshape(T, 6 * m, 6)
    x0, _, _ = qr_solve(A, d.reshape(T, -1))
    return gauss_newton(robot, q, w, d, np.ones(d.shape, bool), tuple(range(6)), noise, x0)


@pytest.fixture(scope="module")
def random_designs(kr240, w_eff):
    """1000 campaigns of 5 tests at poses drawn from the zones, exact fits."""
    rng = np.random.default_rng(2024)
    noise = NoiseModel()
    pool = build_pool(kr240, kr240.nominal_stiffness, w_eff, 400, rng)
    q = pool.q[rng.integers(0, 400, (TRIALS, 5))]
    qm, w, d = _campaigns(kr240, q, w_eff, kr240.nominal_stiffness, noise, rng)
    return qm, w, d, _fit(kr240, qm, w, d, noise), noise


def test_intervals_cover_the_truth_95_percent(kr240, random_designs):
    *_, gn, _ = random_designs
    assert np.all(gn.converged)
    se = np.sqrt(np.diagonal(gn.cov_x, axis1=-2, axis2=-1))
    ci = stiffness_interval(gn.x, se, critical_value(0.95))
    k = kr240.nominal_stiffness
    covered = (ci[..., 0] <= k) & (k <= ci[..., 1])
    rate = covered.mean(axis=0)
    assert np.all((rate >= 0.92) & (rate <= 0.98)), rate


def test_spread_matches_the_predicted_covariance(kr240, random_designs):
    """Standardised errors (x - x_true) / se have unit spread and no bias, per joint."""
    *_, gn, _ = random_designs
    se = np.sqrt(np.diagonal(gn.cov_x, axis1=-2, axis2=-1))
    z = (gn.x - 1 / kr240.nominal_stiffness) / se
    assert np.all(np.abs(z.std(axis=0) - 1) < 0.1), z.std(axis=0)
    assert np.all(np.abs(z.mean(axis=0)) < 0.1), z.mean(axis=0)


def test_fixed_design_spread_matches_covariance(kr240, zone_poses, w_eff):
    """Same 5 poses in every trial: the std of x over trials equals the predicted se (+-8 %)."""
    rng = np.random.default_rng(11)
    noise = NoiseModel()
    q = np.broadcast_to(zone_poses[:5], (600, 5, 6)).copy()
    qm, w, d = _campaigns(kr240, q, w_eff, kr240.nominal_stiffness, noise, rng)
    gn = _fit(kr240, qm, w, d, noise)
    se = np.sqrt(np.diagonal(gn.cov_x, axis1=-2, axis2=-1))
    ratio = gn.x.std(axis=0, ddof=1) / np.sqrt(np.mean(se**2, axis=0))
    assert np.all(np.abs(ratio - 1) < 0.08), ratio


def test_identify_reports_the_batched_covariance(kr240, random_designs):
    qm, w, d, gn, noise = random_designs
    tests = TestArrays(np.array([f"P{i}" for i in range(5)]), qm[0], w[0], d[0],
                       np.ones((5, 6), bool), np.arange(5) + 2)
    res = identify(kr240, tests, "exact", noise=noise, validate=False)
    # the batched Gauss-Newton without the wrench errors-in-variables correction: apply it
    S = wrench_eiv_matrix(jacobian(kr240, tests.q), noise.wrench_sigma_at(tests.w) ** 2,
                          whitening(gn.cov[0]))
    x_c, bread_c = corrected(gn.x[0], gn.cov_x[0], S)
    assert np.max(np.abs(x_c / gn.x[0] - 1)) > 1e-6  # the correction is there to see
    np.testing.assert_allclose(res.x, x_c, rtol=1e-7)
    # sandwich of the corrected estimator: bread_c (F^T W F) bread_c
    np.testing.assert_allclose(res.cov_x, bread_c @ np.linalg.inv(gn.cov_x[0]) @ bread_c,
                               rtol=1e-6)
    se_x = np.sqrt(np.diag(res.cov_x))
    np.testing.assert_allclose(res.se_k, se_x / res.x**2, rtol=1e-12)
    # the encoder noise's bias in J is added as a systematic term (~1e-9 of x here)
    b_q = np.abs(res.encoder_eiv["bias_of_compliance_rad_per_Nm"])
    assert np.all(b_q < 1e-8 * res.x)
    np.testing.assert_allclose(res.ci[:, 0], 1 / (res.x + 1.959963984540054 * se_x + b_q),
                               rtol=1e-12)


def test_stiffness_interval_maps_the_compliance_interval():
    x = np.array([2.0, 1.0, -1.0])
    se = np.array([0.5, 1.0, 0.1])
    ci = stiffness_interval(x, se, 2.0)
    np.testing.assert_allclose(ci[0], [1 / 3, 1.0])
    assert ci[1, 0] == pytest.approx(1 / 3) and np.isinf(ci[1, 1])
    assert np.all(np.isnan(ci[2]))
    assert critical_value(0.95) == pytest.approx(1.959963984540054)
    assert critical_value(0.95, 10) == pytest.approx(2.2281388519649385)


def test_outlier_is_flagged_and_located(kr240, zone_poses, w_eff):
    noise = NoiseModel()
    tests = simulate(kr240, zone_poses[:8], w_eff, kr240.nominal_stiffness, noise, seed=3)
    clean = identify(kr240, tests, "exact", noise=noise, validate=False)
    # studentized residuals of clean data are ~N(0, 1): 48 of them stay below 4
    assert clean.residuals["studentized"].abs().max() < 4
    tests.d[4, 1] += 0.5e-3  # a gross error of 0.5 mm on dy of test 5 (CSV line 6)
    res = identify(kr240, tests, "exact", noise=noise, validate=False)
    worst = res.residuals.loc[res.residuals["studentized"].abs().idxmax()]
    assert (worst["line"], worst["pose"], worst["component"]) == (6, "P5", "dy")
    assert worst["outlier"] and abs(worst["studentized"]) > 10
    # Sidak threshold over the 48 residuals at 1 % family-wise, computed independently
    n = len(res.residuals)
    assert n == 48
    assert res.outlier_threshold == pytest.approx(stats.norm.ppf(1 - (1 - 0.99 ** (1 / n)) / 2))
    # the sequential test sets aside the glitch alone; ``outlier`` is every residual
    # beyond the threshold at the fit reported (the glitch pulls a neighbour beyond it)
    assert int(res.residuals["set_aside"].sum()) == 1
    assert res.residuals.loc[res.residuals["set_aside"], "line"].tolist() == [6]
    beyond = int((res.residuals["studentized"].abs() > res.outlier_threshold).sum())
    assert int(res.residuals["outlier"].sum()) == beyond >= 1
    assert any(f"{beyond} outlier residual(s)" in w and "line 6 (pose P5) dy" in w
               and "set aside 1" in w for w in res.warnings)


def test_outlier_threshold_counts_the_residuals(kr240, zone_poses, w_eff):
    """A 1 mm glitch beside two innocent residuals beyond 3 sigma: only the glitch is flagged."""
    noise = NoiseModel()
    # seed chosen so that two innocent residuals exceed 3 sigma (found by a scan of seeds)
    tests = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, noise, seed=13)
    tests.d[4, 2] += 1e-3  # dz of test 5, CSV line 6
    fit = identify(kr240, tests, "exact", noise=noise, validate=False)
    res = fit.residuals
    glitch = (res["line"] == 6) & (res["component"] == "dz")
    innocent = res[~glitch]
    assert int((innocent["studentized"].abs() > 3).sum()) == 2  # a fixed 3-sigma cut flags them
    assert not innocent["set_aside"].any()
    assert res.loc[glitch, "outlier"].all() and res.loc[glitch, "set_aside"].all()
    assert (res["outlier"] == (res["studentized"].abs() > fit.outlier_threshold)).all()


def test_noise_underestimated_is_detected_and_residual_mode_widens(kr240, zone_poses, w_eff):
    """Data 3 x noisier than the noise model says: chi-square ~ 9, intervals x sqrt(chi2)."""
    true_noise = NoiseModel(translation_sigma_override=60e-6, rotation_sigma_override=450e-6,
                            force_sigma=0.0, moment_sigma=0.0)
    model_noise = NoiseModel(translation_sigma_override=20e-6, rotation_sigma_override=150e-6,
                             force_sigma=0.0, moment_sigma=0.0)
    tests = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, true_noise, seed=5)
    res = identify(kr240, tests, "exact", noise=model_noise, validate=False)
    assert 5 < res.chi2_reduced < 15  # about 9 = 3^2
    assert any("do not match the noise model" in w for w in res.warnings)
    wide = identify(kr240, tests, "exact", noise=model_noise, covariance="residual",
                    validate=False)
    ratio = np.sqrt(np.diag(wide.cov_x) / np.diag(res.cov_x))
    np.testing.assert_allclose(ratio, np.sqrt(res.chi2_reduced), rtol=1e-9)
