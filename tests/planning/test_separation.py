"""Minimum joint-space separation between planned poses ([thresholds] min_pose_separation_deg)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import InputError
from campaign.planning.design import greedy_exchange, random_design
from campaign.planning.planner import make_plan
from campaign.planning.separation import (
    DEFAULT_MIN_SEPARATION_DEG,
    Separation,
    min_pairwise_distance,
)

DEG = np.pi / 180


def _poses_deg(plan) -> np.ndarray:
    df = plan.to_frame().drop_duplicates("pose")
    return df[[f"q{j}_model_deg" for j in range(1, 7)]].to_numpy()


def _with_separation(protocol, deg):
    return protocol.model_copy(update={"thresholds": protocol.thresholds.model_copy(
        update={"min_pose_separation_deg": deg})})


def test_default_and_blocking():
    assert DEFAULT_MIN_SEPARATION_DEG == 5.0
    q = np.array([[0, 0], [3, 0], [6, 0], [0, 4.9], [0, 5.1]], dtype=float) * DEG
    sep = Separation(q, np.arange(5), 5 * DEG)
    assert list(sep.blocked([0])) == [True, True, False, True, False]
    assert sep.conflicts(1, [2]) and not sep.conflicts(2, [0])


def test_design_algorithms_keep_poses_apart():
    rng = np.random.default_rng(0)
    q = rng.uniform(-20, 20, (400, 3)) * DEG  # candidates ~2-4 deg from their neighbours
    A = rng.normal(size=(400, 4, 3))
    # ten times the information within 6 deg of the origin: an optimal design packs there
    near = np.linalg.norm(q, axis=1) < 6 * DEG
    F = np.einsum("nri,nrj->nij", A, A) * np.where(near, 10.0, 1.0)[:, None, None]
    group, zone = np.arange(400), np.arange(400) % 3
    sep = Separation(q, group, 8 * DEG)
    for picks in (greedy_exchange(F, group, 6, sep=sep), random_design(group, zone, 6, 1, sep)):
        assert len(picks) == 6 and min_pairwise_distance(q[picks] / DEG) >= 8.0
    # without it the D-optimal choice packs poses closer than that
    assert min_pairwise_distance(q[greedy_exchange(F, group, 6)] / DEG) < 8.0


@pytest.mark.parametrize("strategy", ["worst-joint", "d-optimal", "zones-random"])
def test_kr240_plan_respects_the_default_separation(kr_protocol, strategy):
    """The built-in KR240-2 protocol (the demo's): its 2-D zones made the worst-joint plan
    put poses 4 and 5 0.3 deg apart; with the default 5 deg they are >= 5 deg apart, and
    the predicted worst joint moves by < 5 % (0.981 -> 0.982 % at 1e4 candidates)."""
    plan = make_plan(kr_protocol, strategy, seed=0, candidates=3000)
    assert min_pairwise_distance(_poses_deg(plan)) >= DEFAULT_MIN_SEPARATION_DEG
    if strategy == "worst-joint":
        free = make_plan(_with_separation(kr_protocol, 0.0), strategy, seed=0, candidates=3000)
        worst = np.max(plan.chosen.se / plan.k_prior)
        assert worst <= 1.05 * np.max(free.chosen.se / free.k_prior)


def test_impossible_separation_is_refused_naming_the_key(kr_protocol):
    with pytest.raises(InputError, match="min_pose_separation_deg") as err:
        make_plan(_with_separation(kr_protocol, 300.0), "d-optimal", seed=0, candidates=500)
    assert "300 deg apart" in str(err.value)


def test_plan_summary_states_the_separation_and_the_closest_pair(kr_protocol):
    """The minimum separation is an assumption of the plan: the summary says its value,
    where it came from (the shipped protocol has no key: the default) and the closest pair
    of the poses chosen, which the plan's own angles reproduce."""
    from campaign.planning.plan_output import summary_dict, summary_text

    for protocol, deg, source in ((kr_protocol, 5.0, "default"),
                                  (_with_separation(kr_protocol, 12.0), 12.0, "protocol")):
        plan = make_plan(protocol, "d-optimal", seed=0, candidates=1500)
        got = summary_dict(plan)["pose_separation"]
        closest = min_pairwise_distance(_poses_deg(plan))
        assert got["min_deg"] == deg and got["source"].startswith(source), got
        assert got["closest_pair_deg"] == pytest.approx(closest, abs=1e-9)
        assert closest >= deg
        text = summary_text(plan)
        assert f"poses at least {deg:g} deg apart" in text
        assert f"closest pair {closest:.2f} deg" in text


def test_analysis_names_where_its_holdout_radius_came_from(kr_protocol):
    """analyze holds out together poses closer than the plan's separation; its assumption
    line says whether the protocol gave the key or the default was used."""
    from campaign.jobs.analyze_assumptions import holdout_deg

    deg, source = holdout_deg(kr_protocol)
    assert deg == DEFAULT_MIN_SEPARATION_DEG and source.startswith("default: protocol")
    deg, source = holdout_deg(_with_separation(kr_protocol, 7.5))
    assert deg == 7.5 and source.endswith("[thresholds] min_pose_separation_deg")
    assert not source.startswith("default")
