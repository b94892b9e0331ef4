"""Linear methods: the linearisation bias is estimated and corrected (or refused).

Coverage of 95 % intervals in seeded Monte-Carlo runs on a robot file the test
writes (5 poses x 3 load cases, tracker 30 um / 40 urad, F/T 0.5 N + 0.5 % of
reading): 95 +- 3 % for every method, at the nominal loads and at twice them.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.corrections.linear_bias import linearisation_bias
from analysis.identification.estimate import identify
from analysis.identification.estimators.fit_solvers import fit_linear
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw
from tests.studies._coverage import NOISE, campaign_setup, coverage


@pytest.fixture(scope="module")
def setup(own_protocol_path):
    return campaign_setup(own_protocol_path)


def _tests(robot, q, W, k, scale, rng):
    qq = np.repeat(q, len(W), axis=0)
    ww = np.tile(W * scale, (len(q), 1))
    d = displacement_screw(robot, qq, k, ww)
    wm = ww + rng.normal(size=ww.shape) * NOISE.wrench_sigma_at(ww)
    dm = d + rng.normal(size=d.shape) * NOISE.displacement_sigma
    qm = qq + rng.normal(size=qq.shape) * NOISE.joint_sigma
    return TestArrays(pose=np.repeat([f"P{i}" for i in range(len(q))], len(W)), q=qm, w=wm,
                      d=dm, measured=np.ones(d.shape, bool), line=np.arange(len(qq)) + 2)


def test_bias_estimate_matches_the_mean_error(setup):
    """G (f(x) - A x) at the estimate predicts the mean OLS error (to 0.15 se)."""
    robot, q, W, k = setup
    rng = np.random.default_rng(4)
    err, est = [], []
    for _ in range(300):
        t = _tests(robot, q, W, k, 1.0, rng)
        f = fit_linear(robot, t, tuple(range(6)), NOISE, weighted=False)
        err.append(f.x - 1 / k)
        est.append(linearisation_bias(robot, t, tuple(range(6)), f.x, f.G, f.predicted))
    err, est = np.array(err), np.array(est)
    sd = err.std(axis=0)
    # the bias is a sizeable part of the spread here (else the test would show nothing)
    assert np.max(np.abs(err.mean(axis=0)) / sd) > 0.3
    assert np.all(np.abs(err.mean(axis=0) - est.mean(axis=0)) < 0.15 * sd)


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_correction_recovers_noise_free_truth(setup, method):
    """Noise-free data without F/T noise (no errors-in-variables term, G A = I): the
    corrected linear estimate is the true compliance to 1e-9 relative, while the raw one
    is off by the linearisation error (> 1e-4 on some joint at twice the loads)."""
    robot, q, W, k = setup
    noise = NoiseModel(translation_sigma_override=30e-6, rotation_sigma_override=40e-6,
                       force_sigma=0.0, moment_sigma=0.0)
    qq = np.repeat(q, len(W), axis=0)
    ww = np.tile(W * 2.0, (len(q), 1))
    d = displacement_screw(robot, qq, k, ww)
    t = TestArrays(pose=np.repeat([f"P{i}" for i in range(len(q))], len(W)), q=qq, w=ww,
                   d=d, measured=np.ones(d.shape, bool), line=np.arange(len(qq)) + 2)
    res = identify(robot, t, method=method, noise=noise, validate=False)
    bias = res.linear_bias
    assert bias["reliable"] and bias["corrected"]
    raw = np.array(bias["raw_joint_stiffness_Nm_per_rad"])
    assert np.max(np.abs(raw / k - 1)) > 1e-4
    np.testing.assert_allclose(res.k, k, rtol=1e-9)
    # the residuals are the exact model's at the corrected estimate: noise-free, ~0
    assert res.chi2_reduced < 1e-12


@pytest.fixture(scope="module")
def ols_twice(setup):
    """The OLS results of the 400 seeded campaigns (seed 2) at twice the loads: the
    campaigns ``coverage(..., "ols", 2.0, 400, seed=2)`` draws (same generator, same order
    of draws), shared by the coverage and the unbiasedness tests (identify ~25 ms each)."""
    robot, q, W, k = setup
    rng = np.random.default_rng(2)
    return tuple(identify(robot, _tests(robot, q, W, k, 2.0, rng), method="ols", noise=NOISE,
                          validate=False) for _ in range(400))


def test_corrected_estimate_is_unbiased(setup, ols_twice):
    """Mean error of the corrected OLS estimate over 400 seeded campaigns at twice the
    loads: within 0.15 of the spread on every joint (the raw one is off by > 0.5)."""
    robot, q, W, k = setup
    raw = np.array([1 / np.array(res.linear_bias["raw_joint_stiffness_Nm_per_rad"]) - 1 / k
                    for res in ols_twice])
    cor = np.array([res.x - 1 / k for res in ols_twice])
    sd = cor.std(axis=0)
    assert np.max(np.abs(raw.mean(axis=0)) / sd) > 0.5
    assert np.all(np.abs(cor.mean(axis=0)) < 0.15 * sd), cor.mean(axis=0) / sd


def test_unreliable_correction_is_refused_and_can_be_accepted(setup, monkeypatch):
    """Beyond the contraction limit the raw estimate is kept, widened by |b|, and the
    plausibility checks refuse it (which --accept-misfit overrides, as every refusal)."""
    import analysis.identification.corrections.linear_bias as lb
    from analysis.identification.checks.plausibility import problems
    from analysis.identification.uncertainty import stiffness_interval

    robot, q, W, k = setup
    t = _tests(robot, q, W, k, 2.0, np.random.default_rng(0))
    good = identify(robot, t, method="wls", noise=NOISE, validate=False)
    assert not any("linearisation bias" in p for p in problems(good, None))
    c = good.linear_bias["contraction"]
    assert 0 < c < lb.CONTRACTION_LIMIT
    monkeypatch.setattr(lb, "CONTRACTION_LIMIT", c / 2)
    bad = identify(robot, t, method="wls", noise=NOISE, validate=False)
    assert not bad.linear_bias["reliable"]
    assert "limit" in bad.linear_bias["reason"]
    raw = np.array(bad.linear_bias["raw_joint_stiffness_Nm_per_rad"])
    np.testing.assert_allclose(bad.k, raw, rtol=1e-12)
    msg = [p for p in problems(bad, None) if p.startswith("linearisation bias")]
    assert len(msg) == 1 and "--method exact" in msg[0]
    # widened by |b|: the half-width of x is 1.96 se + |b|
    x = 1 / bad.k
    se_x = bad.se_k * x**2
    b = np.abs(bad.linear_bias["bias_of_compliance_rad_per_Nm"])
    lo = stiffness_interval(x, se_x + b / 1.959964, 1.959964)
    np.testing.assert_allclose(bad.ci, lo, rtol=1e-6)


def test_a_fit_without_its_prediction_gets_the_right_one_back(setup):
    """identify lets the raw prediction A x_hat go while the correction runs (one (m, 6)
    array held at a time): a reliable correction gives the fit f(x_c), the very array it
    made; an unreliable one A x_hat made again, equal to the fit's own bit for bit."""
    from dataclasses import replace

    from analysis.identification.corrections.linear_bias import (
        correct_linear_bias,
        corrected_fit,
    )
    from analysis.identification.linalg.sandwich import sandwich

    robot, q, W, k = setup
    t = _tests(robot, q, W, k, 2.0, np.random.default_rng(3))
    joints = tuple(range(6))
    fit = fit_linear(robot, t, joints, NOISE, weighted=False)
    se = np.sqrt(np.diag(sandwich(fit.A, fit.cov, fit.bread, fit.Linv)))
    bare = replace(fit, predicted=None)
    good = correct_linear_bias(robot, t, joints, bare, se, "ols")
    bad = correct_linear_bias(robot, t, joints, bare, se, "ols", limit=0.0)
    assert good.reliable and not bad.reliable
    assert corrected_fit(bare, good).predicted is good.predicted
    assert not np.array_equal(good.predicted, fit.predicted)  # f(x_c) is not A x_hat
    np.testing.assert_array_equal(corrected_fit(bare, bad).predicted, fit.predicted)
    assert corrected_fit(fit, bad) is fit


def test_linear_result_states_the_correction(setup):
    robot, q, W, k = setup
    t = _tests(robot, q, W, k, 1.0, np.random.default_rng(0))
    res = identify(robot, t, method="wls", noise=NOISE, validate=False)
    assert any("linearisation bias corrected" in w for w in res.warnings)
    d = res.to_dict()["linearisation_bias"]
    # results.json: the raw and the corrected k; the corrected one is the result
    np.testing.assert_allclose(d["corrected_joint_stiffness_Nm_per_rad"], res.k, rtol=1e-12)
    assert d["raw_joint_stiffness_Nm_per_rad"] != d["corrected_joint_stiffness_Nm_per_rad"]
    assert identify(robot, t, method="exact", noise=NOISE,
                    validate=False).linear_bias is None


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_coverage_linear_quick(setup, ols_twice, method):
    """400 campaigns per load (binomial sd 1.1 %): 95 +- 3 % per joint, nominal and 2x."""
    robot, q, W, k = setup
    for scale in (1.0, 2.0):
        if (method, scale) == ("ols", 2.0):  # the shared campaigns, counted as coverage() does
            given = [r for r in ols_twice if r.linear_bias is None or r.linear_bias["reliable"]]
            cov = np.mean([(r.ci[:, 0] <= k) & (k <= r.ci[:, 1]) for r in given], axis=0)
            given = len(given)
        else:
            cov, given = coverage(robot, q, W, k, method, scale, 400, seed=2)
        assert given == 400
        assert np.all(np.abs(cov - 0.95) <= 0.03), (scale, cov)


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1.0, 2.0])
@pytest.mark.parametrize("method", ["ols", "wls", "exact"])
def test_coverage_every_method(setup, method, scale):
    robot, q, W, k = setup
    cov, given = coverage(robot, q, W, k, method, scale, 1000, seed=3)
    assert given == 1000
    assert np.all(np.abs(cov - 0.95) <= 0.03), cov
