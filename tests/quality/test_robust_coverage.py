"""Robust fits (Huber, Tukey): coverage of 95 % intervals, clean data and data with glitches.

Same seeded Monte-Carlo as the Gaussian fits' (``_coverage.py``: the test-written 6R arm,
5 poses x 3 load cases, tracker 30 um / 40 urad, F/T 0.5 N + 0.5 % of reading); glitches
(``_coverage.Glitches``): each test with probability 0.1 has one gross error of 20 sigma,
on a tracker component or on an F/T component. The table of 1000 campaigns per cell is in
docs/identification.md (``python -m tests.quality.coverage_study --robust``).
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.quality._coverage import NOISE, Glitches, campaign_setup, coverage

#: quick version: 150 campaigns per cell, binomial sd of a 95 % coverage 1.8 %; the
#: tolerance 5 % is 2.8 sd (24 seeded checks: a true 95 % passes, a true 89 % fails)
QUICK_TRIALS = 150
QUICK_TOL = 0.05


@pytest.fixture(scope="module")
def setup(own_protocol_path):
    return campaign_setup(own_protocol_path)


def test_glitch_model(setup):
    """10 % of the tests get one 20-sigma error, half tracker and half F/T, nothing else."""
    robot, q, W, k = setup
    rng = np.random.default_rng(0)
    m = 20000
    ww = np.tile(W, (m // len(W) + 1, 1))[:m]
    dm = np.zeros((m, 6))
    d2, w2 = Glitches().add(rng, dm, ww, ww, NOISE)
    dd = d2 != 0
    dw = w2 != ww
    # one component at most per test, on one instrument
    assert np.all(dd.sum(1) + dw.sum(1) <= 1)
    frac = (dd.any(1) | dw.any(1)).mean()
    assert abs(frac - 0.1) < 0.01  # binomial sd 0.002
    assert abs(dd.any(1).mean() - 0.05) < 0.006
    rows, cols = np.nonzero(dd)
    np.testing.assert_allclose(np.abs(d2[rows, cols]), 20 * NOISE.displacement_sigma[cols])
    rows, cols = np.nonzero(dw)
    np.testing.assert_allclose(np.abs(w2 - ww)[rows, cols],
                               20 * NOISE.wrench_sigma_at(ww)[rows, cols])


def test_glitches_break_the_gaussian_fit(setup):
    """Without a robust fit, the glitches take the coverage well below 95 % (75-83 %)."""
    robot, q, W, k = setup
    cov, given = coverage(robot, q, W, k, "wls", 1.0, QUICK_TRIALS, seed=5,
                          glitches=Glitches())
    assert given >= 0.98 * QUICK_TRIALS
    assert np.all(cov < 0.9), cov


#: glitched campaigns: the measured miss (1000 campaigns per cell, docs/identification.md:
#: 88-96 %, the intervals too narrow by the glitches' remaining influence); the quick test
#: holds the line at 95 - 8 % (4.5 binomial sd of 150 campaigns below the worst cell's 88 %
#: would be 80 %; 87 % fails a regression of a few points)
GLITCHED_FLOOR = 0.87


@pytest.mark.parametrize("robust", ["huber", "tukey"])
def test_robust_coverage_quick(setup, robust):
    """Robust wls, nominal loads: clean 95 +- 5 % per joint; glitched >= 87 % (150 each)."""
    robot, q, W, k = setup
    cov, given = coverage(robot, q, W, k, "wls", 1.0, QUICK_TRIALS, seed=5, robust=robust)
    assert given == QUICK_TRIALS
    assert np.all(np.abs(cov - 0.95) <= QUICK_TOL), cov
    cov, given = coverage(robot, q, W, k, "wls", 1.0, QUICK_TRIALS, seed=5, robust=robust,
                          glitches=Glitches())
    # a glitched campaign may be refused (identify's InputError or an unreliable
    # linearisation-bias correction): not counted
    assert given >= 0.95 * QUICK_TRIALS
    assert np.all(cov >= GLITCHED_FLOOR) and np.all(cov <= 0.95 + QUICK_TOL), cov


@pytest.mark.slow
@pytest.mark.parametrize("glitches", [None, pytest.param(Glitches(), marks=pytest.mark.xfail(
    reason="robust intervals too narrow with glitches (docs/identification.md)"))],
    ids=["clean", "glitches"])
@pytest.mark.parametrize("scale", [1.0, 2.0])
@pytest.mark.parametrize("method", ["wls", "exact"])
@pytest.mark.parametrize("robust", ["huber", "tukey"])
def test_robust_coverage_every_cell(setup, robust, method, scale, glitches):
    """The table's cells (1000 campaigns, binomial sd 0.69 %): 95 +- 3 % per joint."""
    robot, q, W, k = setup
    cov, given = coverage(robot, q, W, k, method, scale, 1000, seed=3, robust=robust,
                          glitches=glitches)
    # wls at twice the loads: 1-4 % refused (the reweighting does not settle in 50 iterations)
    assert given >= 950
    assert np.all(np.abs(cov - 0.95) <= 0.03), cov
