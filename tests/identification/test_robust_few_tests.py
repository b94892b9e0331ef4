"""A robust fit with no more tests than joints is refused: its covariance is estimated
from its G tests (one scale per test), and with G <= p no test is left over the fitted
joints. The audit found 6 tests and 6
joints accepted with the text "Student t with G - p = 1 degrees of freedom" (G - p was 0;
the dof was clamped to 1 and the interval shown without a word)."""

from __future__ import annotations

import pytest

from analysis.identification.checks.plausibility import problems
from analysis.identification.estimate import identify
from analysis.identification.noise import NoiseModel

from ._sim import simulate

NOISE = NoiseModel()


@pytest.mark.parametrize("m, refused", [(6, True), (8, False)])
def test_robust_fit_needs_more_tests_than_joints(kr240, zone_poses, w_eff, m, refused):
    k0 = kr240.nominal_stiffness
    tests = simulate(kr240, zone_poses[:m], w_eff, k0, NOISE, seed=5)
    res = identify(kr240, tests, "exact", noise=NOISE, validate=False, robust="huber")
    cov = res.robust["covariance"]
    assert cov["clusters"] == m
    found = [p for p in problems(res, k0) if p.startswith("too few tests for the robust")]
    if refused:
        assert len(found) == 1
        assert "G = 6 tests for p = 6 fitted joints" in found[0]
        assert "(G - p = 0; at least 7 tests" in found[0]
        assert "--robust none" in found[0]
        assert "G - p = 0: too few tests" in cov["interval"]
    else:
        assert found == []
        assert cov["interval"] == ("Student t, each joint's degrees of freedom by "
                                   "Satterthwaite")
        # Satterthwaite's per joint: between 1 and 6 G (G equal tests of 6 components)
        assert all(1 <= v <= 6 * m for v in cov["degrees_of_freedom"])
    # the Gaussian fit of the same tests is not concerned (its interval rests on the
    # noise figures)
    gauss = identify(kr240, tests, "exact", noise=NOISE, validate=False)
    assert not any(p.startswith("too few tests") for p in problems(gauss, k0))


def test_negative_stiffness_check_uses_the_intervals_student_t(kr240, zone_poses, w_eff):
    """The negative-stiffness check judges a joint at the critical value of the result's
    own interval: for a robust fit, Student t with that joint's Satterthwaite dof (the
    audit found the normal's 1.96 there). A compliance 2.0 se below 0 is refused at the
    normal's 1.96 but not at t's > 2.0 (8 tests: dof well below 60, where t(dof, 97.5 %)
    falls under 2.0)."""
    import dataclasses

    import numpy as np

    from analysis.identification.uncertainty import critical_value

    k0 = kr240.nominal_stiffness
    tests = simulate(kr240, zone_poses[:8], w_eff, k0, NOISE, seed=5)
    res = identify(kr240, tests, "exact", noise=NOISE, validate=False, robust="huber")
    dof = np.array(res.robust["covariance"]["degrees_of_freedom"])
    j = int(np.argmin(dof))
    assert critical_value(0.95, dof[j]) > 2.0 > critical_value(0.95)
    se = np.sqrt(np.diag(res.cov_x))
    x = np.array(res.x, dtype=float)
    x[res.joints[j]] = -2.0 * se[j]
    moved = dataclasses.replace(res, x=x)
    negative = [p for p in problems(moved, k0) if p.startswith("negative stiffness")]
    assert negative == []
    x[res.joints[j]] = -2.0 * se[j] - (critical_value(0.95, dof[j]) - 2.0) * se[j] * 1.01
    negative = [p for p in problems(dataclasses.replace(res, x=x), k0)
                if p.startswith("negative stiffness")]
    assert len(negative) == 1 and f"x{res.joints[j] + 1} = 1/k" in negative[0]
