"""The optimal design beats the paper's random zone practice, predicted and by Monte-Carlo."""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.linear_model import design_matrix
from analysis.kinetostatics.equilibrium import displacement_screw
from campaign.planning.candidates import Candidates
from campaign.planning.design import information, predicted_se, random_design, scaled_blocks

#: stated margin: the D-optimal KR240-2 plan (seed 0, 1e4 candidates) has a geometric
#: mean predicted standard error of k at least 1.3 times lower than the random zone
#: design of the same seed (observed 1.43), and no k's more than 15 % higher: the
#: determinant trades k4 (observed ratio 0.92) for the others (1.12 for k5 .. 2.10 for k3)
MARGIN_MEAN = 1.3
MARGIN_EACH = 0.85
TRIALS = 2000


def _gmean(x):
    return float(np.exp(np.mean(np.log(x))))


def test_predicted_spread_margin(kr_plan):
    ratio = kr_plan.random.se / kr_plan.chosen.se
    assert _gmean(ratio) >= MARGIN_MEAN
    assert np.all(ratio >= MARGIN_EACH)
    assert kr_plan.chosen.log_det > kr_plan.random.log_det + 2.0


def test_design_beats_200_random_zone_designs(kr_plan):
    """Not only the same-seed random design: the D-optimal design beats every one of 200."""
    cand: Candidates = kr_plan.candidates
    pose, case = np.nonzero(cand.valid)
    F = information(scaled_blocks(cand.J[pose], kr_plan.protocol.wrenches()[case],
                                  kr_plan.sigma, kr_plan.k_prior))
    mine = _gmean(kr_plan.chosen.se / kr_plan.k_prior)
    others = []
    for s in range(200):
        picks = random_design(pose, cand.zone[pose], 5, 1000 + s)
        others.append(_gmean(predicted_se(F[picks].sum(0), kr_plan.k_prior) / kr_plan.k_prior))
    assert mine < min(others)
    assert np.median(others) / mine > 1.3


def _monte_carlo_std(plan, design, seed):
    """Empirical std of k identified by least squares from simulated noisy tests."""
    cand = plan.candidates
    q = cand.q[design.pose]
    w = plan.protocol.wrenches()[design.case]
    k_true = plan.k_prior
    exact = displacement_screw(plan.robot, q, k_true, w)  # (t, 6), K_C included
    rng = np.random.default_rng(seed)
    noise = rng.normal(size=(TRIALS, *exact.shape)) * plan.sigma
    measured = (exact + noise).reshape(TRIALS, -1).T  # (6t, trials)
    weights = np.tile(1.0 / plan.sigma, len(q))
    A = design_matrix(plan.robot, q, w) * weights[:, None]
    x, *_ = np.linalg.lstsq(A, measured * weights[:, None], rcond=None)
    k = 1.0 / x.T
    return k.std(axis=0, ddof=1), k.mean(axis=0)


def test_monte_carlo_confirms_margin(kr_plan):
    std_opt, mean_opt = _monte_carlo_std(kr_plan, kr_plan.chosen, seed=11)
    std_rnd, mean_rnd = _monte_carlo_std(kr_plan, kr_plan.random, seed=12)
    # the first-order prediction holds to 10 % with 2000 trials (sampling error ~1.6 %)
    assert np.allclose(std_opt, kr_plan.chosen.se, rtol=0.10)
    assert np.allclose(std_rnd, kr_plan.random.se, rtol=0.10)
    ratio = std_rnd / std_opt
    assert _gmean(ratio) >= MARGIN_MEAN
    assert np.all(ratio >= MARGIN_EACH)
    # identified values are near the truth (the linear model neglects K_C: < 3 %)
    assert np.allclose(mean_opt, kr_plan.k_prior, rtol=0.03)
