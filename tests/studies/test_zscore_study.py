"""z-scores of the exact fit's k over seeded campaigns (issue 22's large-N target).

The target: over >= 20 seeds, the mean z of every joint within +-0.5 and its standard
deviation within 0.8-1.25 (:mod:`tests.studies.zscore_study`; 1e4, 1e5 and 1e6 tests in
docs/identification.md). Here: 1e4 tests against the target over 80 seeds (slow), 1e3 tests with
tolerances from the sampling spread of 60 seeds, and the bias alone at 1e4 tests from
antithetic pairs, which bounds it at 1e6 tests.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.noise import NoiseModel
from tests.studies import linear_response, zscore_study


def test_small_campaigns_z_centred_and_unit_spread():
    """60 campaigns of 1000 tests (~6 s CPU). The mean of 60 z has a standard error of
    0.13: |mean| <= 0.5 is 3.9 of them; the sample sd of 60 draws has a spread of 0.09:
    0.75-1.30 is -2.7..+3.3 of it (both per joint, six joints). Measured (300 seeds):
    means -0.07..+0.05, sds 0.93-1.05."""
    s = zscore_study.summarize(zscore_study.zscores(1000, 60))
    assert np.all(np.abs(s["mean"]) <= 0.5), s["mean"]
    assert np.all((np.array(s["std"]) >= 0.75) & (np.array(s["std"]) <= 1.30)), s["std"]


def test_bias_alone_at_1e4_bounds_it_at_1e6():
    """Antithetic pairs (every noise draw negated, the scatter cancels) at 1e4 tests: the
    bias of every k within 0.05 se (measured over 30 pairs: |mean z_pair| <= 0.006, its
    standard error <= 0.005). A bias of fixed relative size grows as sqrt(N) in standard
    errors, so this bounds it at 1e6 tests by 0.5 se (the wrench errors-in-variables bias
    left uncorrected was 0.8-1.4 se here, 8-14 at 1e6)."""
    pairs = [zscore_study.antithetic_pair(10_000, 1000 + s) for s in range(3)]
    z_pair = np.mean([p["z_pair"] for p in pairs], axis=0)
    assert np.all(np.abs(z_pair) <= 0.05), z_pair
    # the pairs cancel the scatter: each member is ~1 se off, their mean is not
    z = np.array([p["z"] for p in pairs])
    assert np.max(np.abs(z)) > 0.5 and np.max(np.abs(z_pair)) < 0.1 * np.max(np.abs(z))


def test_pairs_see_a_wrong_ft_figure():
    """The same check fails when the fit's F/T figures are twice the simulated ones (the
    errors-in-variables correction then removes four times the attenuation): the pairs
    resolve the bias this leaves (measured, seed 1000: z_pair -1.6, -2.3, -2.1 on k1..k3)."""
    wrong = NoiseModel(force_sigma=2 * NoiseModel().force_sigma,
                       moment_sigma=2 * NoiseModel().moment_sigma)
    pair = zscore_study.antithetic_pair(10_000, 1000, fitted=wrong)
    assert np.max(np.abs(pair["z_pair"])) > 0.5, pair["z_pair"]


def test_noise_free_campaign_gives_the_true_k():
    """No noise anywhere in the simulation (the fit keeps the tracker's weights): every
    term of the error that does not come from the noise -- the simulation's equilibrium
    tolerance, the Gauss-Newton stop, the clip at the joint limits, float accumulation --
    is what is left. Measured: <= 3.5e-11 of k at 1e4 tests, <= 1.3e-13 at 1e6 (seed
    1000), against a standard error of 2e-5 of k3 at 1e6: 1e-6 se at most."""
    r = zscore_study.campaign(5000, 1000, ())
    assert np.max(np.abs(r["rel_err"])) < 1e-9, r["rel_err"]


def test_fit_error_is_the_noise_response_with_the_interval_variance():
    """The exact fit's z of one campaign equals the first-order response of its estimate
    to that campaign's own noise draws (:mod:`tests.studies.linear_response`, no fit), and
    that response's variance given the poses and loads, with the true per-test noise
    covariance, is the interval's to 0.3 % (measured 1.000-1.003 at 2000, 1e4, 1e5 and 1e6
    tests): nothing outside the interval at any N. Measured at 2000 tests, seed 1000:
    |z_fit - z_lin| <= 0.034 (the second-order terms)."""
    lin = linear_response.linear_response(2000, 1000)
    fit = zscore_study.campaign(2000, 1000)
    assert np.all(np.abs(np.array(lin["var_ratio"]) - 1) < 0.01), lin["var_ratio"]
    assert np.max(np.abs(np.array(fit["z"]) - lin["z_lin"])) < 0.1, (fit["z"], lin["z_lin"])
    # the parts add up, and the tracker and the F/T sensor both matter (z of ~1 each)
    parts = np.array(lin["z_d"]) + lin["z_w"] + lin["z_q"]
    assert np.allclose(parts, lin["z_lin"], atol=1e-12)
    assert np.max(np.abs(lin["z_d"])) > 0.3 and np.max(np.abs(lin["z_w"])) > 0.3


def test_linear_response_sees_a_wrong_tracker_figure():
    """The variance check fails when the simulated tracker noise is 1.5 times the figure
    the fit weights with: the interval is then too narrow, most on k6 (var_ratio ~2.2
    there, 1.5^2 of its tracker share 0.99)."""
    base = NoiseModel()
    noisier = NoiseModel(translation_sigma_override=1.5 * base.translation_sigma,
                         rotation_sigma_override=1.5 * base.rotation_sigma)
    lin = linear_response.linear_response(1000, 1000, noise=noisier, fitted=base)
    assert lin["var_ratio"][5] > 2.0 and min(lin["var_ratio"]) > 1.2, lin["var_ratio"]


def test_sources_switch_noise_off():
    sim, fit = zscore_study.noise_models(("tracker",))
    assert sim.force_sigma == fit.force_sigma == 0.0 and fit.joint_sigma == 0.0
    assert sim.translation_sigma == NoiseModel().translation_sigma
    sim, fit = zscore_study.noise_models(("ft",))
    assert sim.translation_sigma == 0.0 and sim.rotation_sigma == 0.0
    # the fit keeps the tracker's figures (its weights), and the F/T ones
    assert fit.translation_sigma == NoiseModel().translation_sigma
    assert fit.force_sigma == NoiseModel().force_sigma and fit.joint_sigma == 0.0
    with pytest.raises(ValueError, match="unknown noise source"):
        zscore_study.noise_models(("laser",))


def test_cli_bad_input_exit_2(capsys):
    assert zscore_study.main(["--sources", "tracker,laser"]) == 2
    assert "--sources" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        zscore_study.main(["--tests", "1e-3"])
    assert exc.value.code == 2


def test_cli_resumes_from_its_file(tmp_path, capsys):
    out = tmp_path / "z.jsonl"
    zscore_study.main(["--tests", "300", "--seeds", "2", "--out", str(out)])
    first = out.read_text().splitlines()
    assert len(first) == 2
    zscore_study.main(["--tests", "300", "--seeds", "3", "--out", str(out)])
    lines = out.read_text().splitlines()
    assert lines[:2] == first and len(lines) == 3  # only the new seed was fitted
    table = capsys.readouterr().out
    assert "| 300 | 3 |" in table


@pytest.mark.slow
def test_1e4_tests_meet_the_target():
    """Issue 22's target at 1e4 tests over 80 seeds (~50 s CPU). Over 20 seeds an
    estimator whose z is exactly N(0, 1) meets the sd band on all six joints with
    probability 0.27 only (the sample sd of 20 draws spreads by 16 %; seeds 1000-1019
    give 0.73 on k4); over 80, 0.96. Measured: means -0.18..+0.12, sds 0.88-1.07."""
    s = zscore_study.summarize(zscore_study.zscores(10_000, 80))
    assert s["seeds"] == 80 and s["within_target"], s


def test_linear_model_response_is_the_exact_one_and_unit_normal():
    """The fast linear-model response (no equilibrium solved; the 1e6-test spread over
    hundreds of seeds in docs/identification.md) equals the exact model's tracker and F/T
    response at 2000 tests within 0.05 (measured 0.021: the model's nonlinearity; the
    encoders' part is 0.001 there), and over 200 campaigns of 500 tests its z has sd
    0.82-1.18 per joint (the sample sd of 200 normal draws has a spread of 0.05: +-3.6 of
    it; measured 0.88-1.03) and means within +-0.25 (3.5 standard errors; measured
    -0.02..+0.06)."""
    fast = linear_response.linear_model_response(2000, 1000)
    full = linear_response.linear_response(2000, 1000)
    diff = np.array(fast["z_lin"]) - (np.array(full["z_d"]) + np.array(full["z_w"]))
    assert np.max(np.abs(diff)) < 0.05, diff
    z = np.array([linear_response.linear_model_response(500, s)["z_lin"] for s in range(200)])
    assert np.all(np.abs(z.mean(axis=0)) < 0.25), z.mean(axis=0)
    sd = z.std(axis=0, ddof=1)
    assert np.all((sd > 0.82) & (sd < 1.18)), sd
