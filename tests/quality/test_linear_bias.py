"""Linear methods: the linearisation bias is estimated, widens the interval or refuses.

Coverage of 95 % intervals in seeded Monte-Carlo runs on a robot file the test
writes (5 poses x 3 load cases, tracker 30 um / 40 urad, F/T 0.5 N + 0.5 % of
reading): 95 +- 3 % for every method that gives a result, at the nominal
loads and at twice them (where OLS and WLS refuse).
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimate import fit_linear, identify
from analysis.identification.linear_bias import BIAS_FRACTION, linearisation_bias
from analysis.identification.measurements import TestArrays
from analysis.kinetostatics.equilibrium import displacement_screw
from tests.quality._coverage import NOISE, campaign_setup, coverage


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


def test_linear_methods_refused_at_twice_the_load(setup):
    robot, q, W, k = setup
    t = _tests(robot, q, W, k, 2.0, np.random.default_rng(0))
    for method in ("ols", "wls"):
        with pytest.raises(InputError, match="use --method exact") as err:
            identify(robot, t, method=method, noise=NOISE, validate=False)
        assert f"limit {BIAS_FRACTION:g}" in str(err.value)
    assert np.all(np.isfinite(identify(robot, t, method="exact", noise=NOISE,
                                       validate=False).k))


def test_linear_result_states_the_widening(setup):
    robot, q, W, k = setup
    t = _tests(robot, q, W, k, 1.0, np.random.default_rng(0))
    res = identify(robot, t, method="wls", noise=NOISE, validate=False)
    assert any("linearisation bias" in w and "widened" in w for w in res.warnings)
    # widened: the interval is wider than the plain 1.96 se one
    from analysis.identification.uncertainty import stiffness_interval
    x = 1 / res.k
    se_x = res.se_k * x**2
    plain = stiffness_interval(x, se_x, 1.959964)
    assert np.all(res.ci[:, 1] - res.ci[:, 0] > plain[:, 1] - plain[:, 0])


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_coverage_linear_quick(setup, method):
    robot, q, W, k = setup
    cov, given = coverage(robot, q, W, k, method, 1.0, 400, seed=2)
    assert given == 400
    assert np.all(np.abs(cov - 0.95) <= 0.03), cov
    _, given2 = coverage(robot, q, W, k, method, 2.0, 20, seed=2)
    assert given2 == 0  # refused at twice the load


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1.0, 2.0])
@pytest.mark.parametrize("method", ["ols", "wls", "exact"])
def test_coverage_every_method(setup, method, scale):
    robot, q, W, k = setup
    cov, given = coverage(robot, q, W, k, method, scale, 1000, seed=3)
    if method == "exact" or scale == 1.0:
        assert given == 1000
    if given:
        assert np.all(np.abs(cov - 0.95) <= 0.03), cov
