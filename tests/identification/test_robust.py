"""Robust fitting (Huber, Tukey IRLS): a 1 mm glitch, clean data, refusals, the CLI."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import integrate, stats

from analysis.errors import InputError
from analysis.identification.checks.plausibility import problems
from analysis.identification.estimate import identify
from analysis.identification.estimators.irls import HUBER_C, TUKEY_C, huber_weight, tukey_weight
from analysis.identification.io.columns import CSV_COLUMNS
from analysis.identification.io.measurements import table_from_arrays, to_csv_frame
from analysis.identification.noise import NoiseModel
from analysis.report.build import robust_blocks
from campaign.cli import main

from ._sim import simulate

NOISE = NoiseModel()


def _efficiency(psi, dpsi) -> float:
    """Asymptotic efficiency (E psi')^2 / E psi^2 of an M-estimator of location, N(0, 1)."""
    e_d = integrate.quad(lambda z: dpsi(z) * stats.norm.pdf(z), -12, 12, limit=200)[0]
    e_2 = integrate.quad(lambda z: psi(z) ** 2 * stats.norm.pdf(z), -12, 12, limit=200)[0]
    return e_d**2 / e_2


def test_weights_and_their_95_percent_efficiency():
    np.testing.assert_allclose(huber_weight(np.array([0.0, 0.5, -1.345, 2.69, -13.45])),
                               [1, 1, 1, 0.5, 0.1])
    np.testing.assert_allclose(tukey_weight(np.array([0.0, TUKEY_C / 2, -TUKEY_C, 10.0])),
                               [1, 0.5625, 0, 0])
    # the constants give 95 % efficiency under Gaussian noise (computed from psi = r w(r))
    c = HUBER_C
    huber = _efficiency(lambda z: np.clip(z, -c, c), lambda z: float(abs(z) <= c))
    t = TUKEY_C
    tukey = _efficiency(lambda z: z * (1 - (z / t) ** 2) ** 2 * (abs(z) < t),
                        lambda z: (1 - (z / t) ** 2) * (1 - 5 * (z / t) ** 2) * (abs(z) < t))
    assert huber == pytest.approx(0.95, abs=0.002)
    assert tukey == pytest.approx(0.95, abs=0.002)


@pytest.fixture(scope="module")
def campaign(kr240, zone_poses, w_eff):
    """12 poses, seeded noise; and the same with 1 mm added to dy of test 5 (CSV line 6)."""
    clean = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, NOISE, seed=3)
    glitch = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, NOISE, seed=3)
    glitch.d[4, 1] += 1e-3
    return clean, glitch


def test_glitch_pulls_the_gaussian_fit_and_not_the_robust_ones(kr240, campaign):
    _, tests = campaign
    k0 = kr240.nominal_stiffness
    gauss = identify(kr240, tests, "exact", noise=NOISE, validate=False)
    assert np.max(np.abs(gauss.k - k0) / gauss.se_k) > 5  # pulled off by the glitch
    assert any(p.startswith("misfit") for p in problems(gauss, k0))
    worst = gauss.residuals.loc[gauss.residuals["studentized"].abs().idxmax()]
    assert (worst["line"], worst["component"], worst["outlier"]) == (6, "dy", True)
    assert gauss.robust is None and gauss.to_dict()["robust"] is None

    for method, limit in (("huber", 0.1), ("tukey", 1e-12)):
        res = identify(kr240, tests, "exact", noise=NOISE, validate=False, robust=method)
        assert np.all((res.ci[:, 0] < k0) & (k0 < res.ci[:, 1])), method
        assert np.max(np.abs(res.k - k0) / res.se_k) < 2
        rob = res.to_dict()["robust"]
        assert rob["method"] == method and rob["constant"] == (HUBER_C if method == "huber"
                                                               else TUKEY_C)
        assert 1 < rob["iterations"] <= 100
        glitch = [d for d in rob["down_weighted"] if (d["line"], d["component"]) == (6, "dy")]
        assert len(glitch) == 1 and glitch[0]["weight"] <= limit
        assert glitch[0]["test"] == 5 and glitch[0]["whitened_residual"] > 20
        assert len(rob["down_weighted"]) <= 3
        # the weight column matches, the glitch is marked and the rest of the fit is believable
        row = res.residuals[(res.residuals["line"] == 6) & (res.residuals["component"] == "dy")]
        assert row["weight"].iloc[0] == pytest.approx(glitch[0]["weight"], abs=1e-15)
        assert row["outlier"].iloc[0]
        assert res.dof == res.n_equations - 6 - len(rob["down_weighted"])
        assert problems(res, k0) == []
        assert any(w.startswith(f"robust fit ({method}") and "line 6 (pose P5) dy" in w
                   for w in res.warnings)


def test_robust_interval_is_the_sandwich_with_student_t(kr240, campaign):
    """The reported covariance is the per-test-scale sandwich (robust_covariance); the
    interval uses Student t with each joint's Satterthwaite degrees of freedom (between 1
    and 6 G = 72 for 12 tests of 6 components); the fixed-weight G Sigma G^T, reported
    beside, stays within a few % of the Gaussian fit's se on clean data, and a zero-weight
    row adds nothing to it."""
    from analysis.identification.uncertainty import critical_value, stiffness_interval

    clean, tests = campaign
    res = identify(kr240, tests, "exact", noise=NOISE, validate=False, robust="tukey")
    gauss_clean = identify(kr240, clean, "exact", noise=NOISE, validate=False)
    cov = res.robust["covariance"]
    dof = np.array(cov["degrees_of_freedom"])
    assert cov["clusters"] == 12 and "Satterthwaite" in cov["interval"]
    assert np.all((dof >= 1) & (dof <= 72)), dof
    se_x = np.sqrt(np.diag(res.cov_x))
    # rtol 1e-6: the encoder-noise term widens the interval by ~1e-9 here
    np.testing.assert_allclose(
        res.ci, stiffness_interval(res.x, se_x, critical_value(0.95, dof)), rtol=1e-6)
    se_fixed = se_x / np.array(cov["se_over_fixed_weights"])
    ratio = se_fixed / np.sqrt(np.diag(gauss_clean.cov_x))
    assert np.all((ratio > 0.9) & (ratio < 1.15)), ratio
    # the per-test scales' sandwich and the cluster sandwich estimate one variance: within
    # a factor 2 of each other on 12 tests (the latter's +-30-50 % scatter)
    r = np.array(cov["se_over_uncorrected_sandwich"])
    assert np.all((r > 0.5) & (r < 2.0)), r


def test_clean_data_robust_equals_gaussian(kr240, campaign):
    clean, _ = campaign
    gauss = identify(kr240, clean, "exact", noise=NOISE, validate=False)
    for method in ("huber", "tukey"):
        res = identify(kr240, clean, "exact", noise=NOISE, validate=False, robust=method)
        # 95 % efficiency: the difference has an rms of ~sqrt(1/0.95 - 1) = 0.23 se
        assert np.max(np.abs(res.k - gauss.k) / gauss.se_k) < 0.5, method
        # the fixed-weight se (the sandwich's own is a 12-test estimate, +-30 %)
        se_fixed = np.sqrt(np.diag(res.cov_x)) / res.robust["covariance"][
            "se_over_fixed_weights"]
        np.testing.assert_allclose(se_fixed, np.sqrt(np.diag(gauss.cov_x)), rtol=0.06)
        down = res.robust["down_weighted"]
        assert len(down) <= 3 and all(d["weight"] > 0.1 for d in down)


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_linear_robust_names_the_glitch(kr240, zone_poses, w_eff, method):
    # at 0.4 x the load, where the linearisation bias is within its limit; ols: the
    # unweighted fit with the robust weights of the whitened residuals
    tests = simulate(kr240, zone_poses, 0.4 * w_eff, kr240.nominal_stiffness, NOISE, seed=3)
    tests.d[4, 1] += 1e-3
    res = identify(kr240, tests, method, noise=NOISE, validate=False, robust="huber")
    glitch = [d for d in res.robust["down_weighted"] if (d["line"], d["component"]) == (6, "dy")]
    assert len(glitch) == 1 and glitch[0]["weight"] < 0.1
    k0 = kr240.nominal_stiffness
    assert np.all((res.ci[:, 0] < k0) & (k0 < res.ci[:, 1])), method


def test_robust_refusals(kr240, campaign, zone_poses, w_eff):
    _, tests = campaign
    with pytest.raises(InputError, match="none, huber, tukey"):
        identify(kr240, tests, "exact", noise=NOISE, validate=False, robust="cauchy")
    # data 3 x noisier than declared: down-weighting would hide the misfit; refused
    loud = NoiseModel(translation_sigma_override=3 * NOISE.translation_sigma,
                      rotation_sigma_override=3 * NOISE.rotation_sigma)
    noisy = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, loud, seed=5)
    res = identify(kr240, noisy, "exact", noise=NOISE, validate=False, robust="huber")
    found = problems(res, kr240.nominal_stiffness)
    assert any(p.startswith("misfit hidden by the robust fit") for p in found)


def test_report_table_lists_the_down_weighted(kr240, campaign):
    _, tests = campaign
    res = identify(kr240, tests, "exact", noise=NOISE, validate=False, robust="tukey")
    blocks = robust_blocks(res)
    table = blocks[-1]
    rows = {(r[1], r[3]): r for r in table.rows}
    assert rows[("6", "dy")][4] == "0" and table.marked[list(rows).index(("6", "dy"))]
    assert robust_blocks(identify(kr240, tests, "exact", noise=NOISE, validate=False)) == []


def test_cli_robust_end_to_end(tmp_path, capsys, kr240, campaign):
    _, tests = campaign
    frame = to_csv_frame(table_from_arrays(tests.pose, tests.q, tests.w, tests.d))
    csv = tmp_path / "tests.csv"
    frame[CSV_COLUMNS].to_csv(csv, index=False)
    base = ["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--no-report"]
    assert main([*base, "--out", str(tmp_path / "gauss")]) == 2
    assert "misfit" in capsys.readouterr().err
    assert main([*base, "--out", str(tmp_path / "tukey"), "--robust", "tukey"]) == 0
    out = capsys.readouterr().out
    assert "robust fitting: tukey IRLS" in out and "line 6 (pose P5) dy weight 0" in out
    res = json.loads((tmp_path / "tukey" / "results.json").read_text())
    assert res["robust"]["method"] == "tukey"
    assert any(d["line"] == 6 and d["component"] == "dy" and d["weight"] == 0
               for d in res["robust"]["down_weighted"])
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    assert np.all(np.abs(k / kr240.nominal_stiffness - 1) < 0.1)
    assert main([*base, "--out", str(tmp_path / "x"), "--robust", "cauchy"]) == 2
    assert "--robust" in capsys.readouterr().err
    assert main(["analyze", "--help"]) == 0
    assert "huber" in capsys.readouterr().out
