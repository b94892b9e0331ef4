"""The worst-joint criterion against random zone designs: predicted and by Monte-Carlo.

Target (issue 14): the worst joint's relative spread at least 30 % below the
median random design drawn from the same zones, and no joint worse than that
median by more than 5 %, on the shipped protocols and on a protocol of a robot
file the test writes.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.studies.design_simulation import identify_campaigns, simulate_campaigns
from campaign.planning.criteria import candidate_information, relative_se
from campaign.planning.design import random_design
from campaign.planning.planner import make_plan
from campaign.protocol import load_protocol

RANDOM_DESIGNS = 201  # the planner's reference designs (seeds seed + 1000 + i)
RANDOM_TRIALS = 300
TRIALS = 2000


def _relative_std(plan, pose, case, trials, seed):
    q = plan.candidates.q[pose]
    w = plan.protocol.wrenches()[case]
    sim = simulate_campaigns(plan.robot, q, w, plan.k_prior, plan.noise,
                             plan.protocol.campaign.repeats, trials, np.random.default_rng(seed))
    x = identify_campaigns(plan.robot, sim, plan.noise, 1.0 / plan.k_prior, "wls")
    return (1.0 / x).std(axis=0, ddof=1) / plan.k_prior, x.std(axis=0, ddof=1) * plan.k_prior


def _check(plan):
    mine = plan.chosen.se / plan.k_prior
    ref = plan.random_median_se / plan.k_prior
    # predicted
    assert mine.max() <= 0.70 * ref.max()
    assert np.all(mine <= 1.05 * ref)
    # Monte-Carlo: the chosen design, and the per-joint median over random zone designs
    cand = plan.candidates
    pose, case = np.nonzero(cand.valid)
    n = plan.protocol.campaign.tests
    sim_mine, _ = _relative_std(plan, plan.chosen.pose, plan.chosen.case, TRIALS, 1)
    sims, sims_x = [], []
    for i in range(RANDOM_DESIGNS):
        picks = random_design(pose, cand.zone[pose], n, plan.seed + 1000 + i)
        k_spread, x_spread = _relative_std(plan, pose[picks], case[picks], RANDOM_TRIALS, 100 + i)
        sims.append(k_spread)
        sims_x.append(x_spread)
    sim_ref = np.median(np.array(sims), axis=0)
    assert sim_mine.max() <= 0.70 * sim_ref.max()
    assert np.all(sim_mine <= 1.05 * sim_ref)
    # the prediction of the random designs' median holds too, in compliance (for k the
    # delta method under-predicts designs with ~15 % relative se by up to ~15 %)
    np.testing.assert_allclose(np.median(np.array(sims_x), axis=0), ref, rtol=0.10)
    np.testing.assert_allclose(sim_mine, mine, rtol=0.10)
    return mine, ref, sim_mine, sim_ref


def test_own_robot_protocol(own_protocol_path):
    _check(make_plan(load_protocol(own_protocol_path), "worst-joint", seed=0,
                     candidates=3000))


def test_kr240_protocol(kr_protocol):
    _check(make_plan(kr_protocol, "worst-joint", seed=0, candidates=3000))


def test_ur10e_protocol(ur_protocol):
    _check(make_plan(ur_protocol, "worst-joint", seed=0, candidates=10000))


def test_weighted_criterion_follows_weights(own_protocol_path):
    """Weighting k6 ten times more lowers its relative se against equal weights."""
    proto = load_protocol(own_protocol_path)
    even = make_plan(proto, "weighted", seed=0, candidates=1500, weights=[1] * 6)
    heavy = make_plan(proto, "weighted", seed=0, candidates=1500, weights=[1] * 5 + [10])
    assert heavy.chosen.se[5] < even.chosen.se[5]
    # the plan's se is the independent information of its tests
    F = candidate_information(heavy.candidates.J[heavy.chosen.pose],
                              proto.wrenches()[heavy.chosen.case], heavy.noise, heavy.k_prior,
                              proto.campaign.repeats).sum(0)
    np.testing.assert_allclose(heavy.chosen.se, heavy.k_prior * relative_se(F), rtol=1e-3)
