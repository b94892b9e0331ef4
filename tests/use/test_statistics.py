"""Seeded Monte-Carlo checks of the uncertainty statements: interval coverage, compare's rates."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.compare.comparison import critical_z, difference_intervals, z_scores
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.kinetostatics.uncertainty import Z95, predict_deflection
from analysis.model.robots import load_robot
from tests.use._campaigns import TRUE_K, identify_campaigns

TRIALS = 400


@pytest.fixture(scope="module")
def kr240():
    return load_robot("kr240-2")


@pytest.fixture(scope="module")
def campaigns(kr240):
    return identify_campaigns(kr240, TRUE_K, TRIALS, seed=11)


def test_deflection_intervals_cover_the_truth_at_95_percent(kr240, campaigns):
    """Each campaign's 95 % interval of the deflection at held-out poses covers the true one.

    Binomial bounds: with 400 campaigns the coverage of one component has a
    standard deviation of 1.1 %; each rate must lie within 0.95 +- 3.3 %.
    """
    x, cov = campaigns
    k_hat = 1.0 / x
    w = np.array([800.0, -1500.0, 1200.0, 60.0, -40.0, 30.0])  # not one of the test loads
    for q_deg in ([15, 50, -195, 30, 40, 20], [-10, 20, 20, -30, 60, 60]):
        q = np.radians(q_deg)
        truth = displacement_screw(kr240, q, TRUE_K, w)
        pred = predict_deflection(kr240, np.broadcast_to(q, (TRIALS, 6)), k_hat, w, cov)
        lo, hi = pred.bounds(Z95)
        rate = np.mean((lo <= truth) & (truth <= hi), axis=0)
        assert np.all(np.abs(rate - 0.95) < 0.033), rate


def test_sensitivity_matches_finite_differences_of_the_equilibrium(kr240):
    q = np.radians([[15, 50, -195, 30, 40, 20]])
    w = np.array([0, 2200, 2200, 200, 200, 0.0])
    x = 1.0 / TRUE_K
    S = predict_deflection(kr240, q, TRUE_K, w).sensitivity[0]
    for j in range(6):
        h = 1e-4 * x[j]
        xp, xm = x.copy(), x.copy()
        xp[j] += h
        xm[j] -= h
        fd = (displacement_screw(kr240, q, 1 / xp, w) - displacement_screw(kr240, q, 1 / xm, w))
        fd = fd[0] / (2 * h)
        # translations exact; rotations to first order in the rotation angle (~1e-2 here)
        assert np.allclose(S[:3, j], fd[:3], rtol=1e-6, atol=1e-9 * np.abs(fd).max())
        assert np.allclose(S[3:, j], fd[3:], rtol=0, atol=1e-2 * np.abs(fd[3:]).max())


def test_compare_false_alarm_rate_and_power(kr240, campaigns):
    """Unchanged robot: any-joint false alarms at most alpha = 5 %; k2 5 % softer: detected."""
    x_a, cov_a = campaigns
    x_b, cov_b = identify_campaigns(kr240, TRUE_K, TRIALS, seed=12)
    var = lambda c: np.diagonal(c, axis1=-2, axis2=-1)  # noqa: E731
    zc = critical_z(0.05, 6)
    alarms = np.any(np.abs(z_scores(x_a, var(cov_a), x_b, var(cov_b))) > zc, axis=1)
    # Bonferroni keeps the family-wise rate <= 5 %; 400 pairs: sd 1.1 %, bound 5 % + 3 sd
    assert alarms.mean() <= 0.05 + 3 * np.sqrt(0.05 * 0.95 / TRIALS)
    soft = TRUE_K.copy()
    soft[1] *= 0.95
    x_c, cov_c = identify_campaigns(kr240, soft, TRIALS, seed=13)
    z = z_scores(x_a, var(cov_a), x_c, var(cov_c))
    assert np.mean(np.abs(z[:, 1]) > zc) >= 0.99  # the change is found
    others = np.delete(z, 1, axis=1)
    assert np.mean(np.any(np.abs(others) > zc, axis=1)) <= 0.05 + 3 * np.sqrt(0.05 * 0.95 / TRIALS)


def test_compare_intervals_cover_at_the_bonferroni_level(kr240, campaigns):
    """The intervals of k_B - k_A, at 1 - alpha/6 each, hold the true difference for all six
    joints together in at least 95 % of the pairs (binomial bound: + 3 sd over 400 pairs),
    and each joint's alone in about 99.2 %; at 1.96 sigma they would not (about 27 %
    of the pairs with a joint missed)."""
    x_a, cov_a = campaigns
    soft = TRUE_K.copy()
    soft[1] *= 0.95
    x_c, cov_c = identify_campaigns(kr240, soft, TRIALS, seed=14)
    var = lambda c: np.diagonal(c, axis1=-2, axis2=-1)  # noqa: E731
    truth = soft - TRUE_K
    zc = critical_z(0.05, 6)
    diff, half = difference_intervals(x_a, var(cov_a), x_c, var(cov_c), zc)
    held = np.abs(diff - truth) <= half
    sd = np.sqrt(0.05 * 0.95 / TRIALS)
    assert np.mean(np.all(held, axis=1)) >= 0.95 - 3 * sd
    assert np.all(np.mean(held, axis=0) >= 1 - 0.05 / 6 - 3 * np.sqrt(0.0083 / TRIALS))
    diff95, half95 = difference_intervals(x_a, var(cov_a), x_c, var(cov_c), 1.959963984540054)
    assert np.mean(np.all(np.abs(diff95 - truth) <= half95, axis=1)) < 0.85
