"""The planner for a model class (issue 32 item 3): its predicted standard errors against a
seeded Monte-Carlo of the class fit on the design, and its criterion against the joint-only
design's."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.io.measurements import TestArrays
from analysis.identification.models.fit import fit_class, link_columns, prepare
from analysis.identification.noise import residual_covariance
from analysis.model.kinematics import jacobian
from campaign.planning import model_class as mc
from campaign.planning.criteria import cartesian_compliance
from campaign.planning.plan_output import summary_dict, summary_text
from campaign.planning.planner import _tests, make_plan

#: a design the links class can identify: 20 poses (120 equations for 6 + up to 42)
TESTS, CANDIDATES, TRIALS = 20, 600, 200


@pytest.fixture(scope="module")
def plans(kr_protocol):
    return {m: make_plan(kr_protocol, "worst-joint", seed=3, candidates=CANDIDATES,
                         tests=TESTS, model=m) for m in ("joints", "links")}


def _simulate(plan, rng, trials):
    """Noisy averaged tests of the plan's design (rows repeats; the truth its prior k, rigid
    links): displacements of the linear model plus Gaussian noise of the planner's
    covariance (no encoder noise)."""
    robot, d = plan.robot, plan.chosen
    q = plan.candidates.q[d.pose]
    w = plan.protocol.wrenches()[d.case]
    J = jacobian(robot, q)
    x = 1.0 / plan.k_prior
    mean = np.einsum("mrj,j->mr", J * np.einsum("mji,mj->mi", J, w)[:, None, :], x)
    S = residual_covariance(plan.noise, cartesian_compliance(J, plan.k_prior), w)
    L = np.linalg.cholesky(S / plan.protocol.campaign.repeats)
    e = np.einsum("mij,tmj->tmi", L, rng.standard_normal((trials, *mean.shape)))
    return q, w, mean[None] + e


def test_predicted_se_of_the_link_entries_is_the_monte_carlo_spread(plans):
    """The planner's se of every kept link entry and of k (encoders left out, as in the
    simulation) against the standard deviation of 200 seeded class fits (``wls``, linear)
    of the same design: within the Monte-Carlo's sampling error (a sample std of 200
    draws is within 1 +- 0.2 of the truth at 4 sigma; their mean within 0.05)."""
    plan = plans["links"]
    spec = mc.ClassSpec(("links",))
    pred = mc.predict(plan.robot, plan.candidates, plan.chosen.pose, plan.chosen.case,
                      plan.protocol.wrenches(), plan.noise, plan.k_prior,
                      plan.protocol.campaign.repeats, spec, encoders=False)
    q, w, D = _simulate(plan, np.random.default_rng(20261207), TRIALS)
    m = len(q)
    group = np.arange(m)
    values, k = [], []
    for t in range(TRIALS):
        tests = TestArrays(pose=np.array([str(i) for i in group]), q=q, w=w, d=D[t],
                           measured=np.ones((m, 6), bool), line=group + 2)
        data = prepare(plan.robot, tests, range(6), 1.0 / plan.k_prior, plan.noise, "wls",
                       None, group)
        if t == 0:
            # the fit keeps as many entries as the planner: the same span (k's se is that
            # span's); which entries of an exactly dependent group its pivoted QR keeps is
            # decided by rounding (here 5 of 30 differ), so the trials are fitted with the
            # planner's choice (``like``, the studies' projection) to compare entry by entry
            own = fit_class(data, ("links",))
            assert len(own.names) == len(pred.names)
            assert own.fixed[0][0] == pred.fixed[0][0] == "C2[6,6], C3[6,6]"
        f = fit_class(data, ("links",), like=SimpleNamespace(names=pred.names, flank_spring=()))
        assert not f.error and f.names == pred.names
        values.append(f.values)
        k.append(f.k)
    ratio = np.std(values, axis=0, ddof=1) / pred.se
    k_ratio = np.std(k, axis=0, ddof=1) / pred.k_se
    assert len(pred.names) >= 20
    assert np.all(np.abs(ratio - 1) < 0.2), ratio
    assert abs(np.mean(ratio) - 1) < 0.05
    assert np.all(np.abs(k_ratio - 1) < 0.2), k_ratio
    # the class's k is marginal over the links: worse than the joint-only prediction
    assert np.all(pred.k_se > plans["joints"].chosen.se * 0.999)


def test_links_design_separates_links_from_joints(plans, kr_protocol):
    """Under the links class, the design made for it has a smaller worst marginal relative
    se of k than the joint-only design: by the criterion (the pool's inputs, the weak
    prior) and by the fit's own rule (what analyze --model links would report)."""
    joint, links = plans["joints"], plans["links"]
    spec = mc.ClassSpec(("links",))
    pose, case, _ = _tests(links.candidates, kr_protocol.loads.selection)
    inp = mc.pool_inputs(links.robot, links.candidates, pose, case, kr_protocol.wrenches(),
                         links.noise, links.k_prior, kr_protocol.campaign.repeats, spec)
    worst = {name: float(np.max(mc.criterion_se(inp, inp.information(p.chosen.picks).sum(0))))
             for name, p in plans.items()}
    assert worst["links"] < 0.9 * worst["joints"], worst
    fit_rule = {name: float(np.max(mc.fit_rule_se(inp, p.chosen.picks)))
                for name, p in plans.items()}
    assert fit_rule["links"] < fit_rule["joints"], fit_rule
    # the plan's own figure is the fit rule's with the encoder term: the same within 1 %
    assert np.max(links.chosen.se / links.k_prior) == pytest.approx(fit_rule["links"],
                                                                    rel=0.01)
    # the joint-only design and its figures are today's (the class only re-ranks)
    assert joint.chosen.model is None and joint.model == "joints"


def test_summary_lists_the_class_parameters_with_units(plans):
    s = summary_dict(plans["links"])
    m = s["model_class"]
    assert m["model"] == "links"
    units = {p["unit"] for p in m["parameters"]}
    assert units <= {"m/N", "rad/N", "rad/(N m)"} and "m/N" in units
    assert all(p["se_design"] > 0 for p in m["parameters"])
    fixed = " ".join(f["parameters"] for f in m["fixed"])
    assert "C2[6,6]" in fixed and "C3[6,6]" in fixed  # joints 3 and 4's rotations
    text = summary_text(plans["links"])
    assert "model class links" in text and "C2[1,1]" in text
    assert "model_class" not in summary_dict(plans["joints"])


def test_compensator_columns_are_the_fits_law():
    """The compensator's columns are a2 t, a2 t^2 (t = q2 - q2ref) of the fit's law, and the
    links' the fit's link regressor."""
    from analysis.identification.estimators.linear_model import design_block
    from analysis.model.robots import load_robot

    robot = load_robot("kr240-2")
    rng = np.random.default_rng(4)
    q = robot.lower + rng.random((5, 6)) * (robot.upper - robot.lower)
    w = rng.normal(size=(5, 6)) * 1e3
    J = jacobian(robot, q)
    E, names = mc.extra_columns(robot, J, q, w, mc.ClassSpec(("compensator", "links")), 0.3)
    a2 = design_block(J, w)[..., 1]
    t = q[:, 1] - 0.3
    np.testing.assert_allclose(E[..., 0], a2 * t[:, None], rtol=1e-13)
    np.testing.assert_allclose(E[..., 1], a2 * (t**2)[:, None], rtol=1e-13)
    np.testing.assert_array_equal(E[..., 2:], link_columns(robot, q, w, (2, 3))[0])
    assert [n[0] for n in names[:3]] == ["c1", "c2", "C2[1,1]"]


@pytest.mark.parametrize("model, why", [("gravity", "not gravity"), ("auto", "not auto"),
                                        ("lost-motion+links", "not lost-motion")])
def test_classes_the_planner_cannot_design_for_are_refused(kr_protocol, model, why):
    with pytest.raises(InputError, match=why):
        mc.planner_class(kr_protocol, model)


def test_protocol_key_default_and_override(kr_protocol):
    assert kr_protocol.campaign.model == "joints"
    assert mc.planner_class(kr_protocol) is None
    spec = mc.planner_class(kr_protocol, "links+compensator")
    assert spec.extras == ("compensator", "links") and spec.links == (2, 3)


def test_protocol_model_key_designs_for_the_compensator(tmp_path):
    """``[campaign] model = "compensator"`` in a protocol file: the plan is made for it (its
    c1, c2 predicted with their units, the q2 spread printed); an unknown class is refused
    at the key's line."""
    from pathlib import Path

    from campaign.protocol import load_protocol

    kr = Path(__file__).resolve().parents[2] / "protocols" / "kr240-2.toml"
    text = kr.read_text().replace('tests = 5 ', 'model = "compensator"\ntests = 8 ', 1)
    path = tmp_path / "p.toml"
    path.write_text(text)
    plan = make_plan(load_protocol(path), "worst-joint", seed=1, candidates=300)
    m = summary_dict(plan)["model_class"]
    assert plan.model == "compensator" and m["model"] == "compensator"
    assert [(p["name"], p["unit"]) for p in m["parameters"]] == [
        ("c1", "rad/(N m) per rad"), ("c2", "rad/(N m) per rad^2")]
    assert m["q2_range_rad"] > 0 and "q2 over the tests" in summary_text(plan)
    path.write_text(text.replace('"compensator"', '"springs"'))
    with pytest.raises(InputError, match="campaign.model"):
        load_protocol(path)


def test_compensator_design_spreads_q2(kr_protocol):
    """Designed for the compensator (KR240-2, 12 tests, 600 candidates, seed 3), the law's
    c1 h/x2 and c2 h^2/x2 are better determined than by the joint-only design (relative se
    0.101 -> 0.081 % and 0.297 -> 0.132 %; q2 std 33.9 -> 38.7 deg) at the cost of
    nothing in the worst k (0.643 -> 0.649 %)."""
    plans = {m: make_plan(kr_protocol, "worst-joint", seed=3, candidates=CANDIDATES, tests=12,
                          model=m) for m in ("joints", "compensator")}
    c = plans["compensator"]
    pose, case, _ = _tests(c.candidates, kr_protocol.loads.selection)
    inp = mc.pool_inputs(c.robot, c.candidates, pose, case, kr_protocol.wrenches(), c.noise,
                         c.k_prior, kr_protocol.campaign.repeats, mc.ClassSpec(("compensator",)))
    assert inp.names == ("c1", "c2")
    r = {m: mc.criterion_se(inp, inp.information(p.chosen.picks).sum(0)) for m, p in
         plans.items()}
    assert np.all(r["compensator"][6:] < 0.9 * r["joints"][6:])
    assert np.max(r["compensator"][:6]) < 1.05 * np.max(r["joints"][:6])
    q2 = {m: np.std(p.candidates.q[p.chosen.pose, 1]) for m, p in plans.items()}
    assert q2["compensator"] > q2["joints"]


def test_a_design_with_no_more_equations_than_parameters_is_flagged():
    """The 5-test plan of the shop protocol under compensator+links: 30 distinct
    equations for 6 k + 24 kept link entries (the study's finding: the class then fits
    the tests' means exactly and auto cannot tell it from links alone)."""
    from campaign.planning.model_class import ClassPrediction, minimum_tests

    def pred(equations, held_out, kept):
        return ClassPrediction("compensator+links", tuple(f"c{i}" for i in range(kept)),
                               ("m/N",) * kept, np.ones(kept), (), np.ones(6),
                               equations=equations, equations_pose_held_out=held_out)

    assert minimum_tests(30) == 10 and minimum_tests(12) == 4 and minimum_tests(6) == 3
    saturated = pred(30, 24, 24)
    assert saturated.parameters == 30
    assert "30 equations for the 30 parameters" in saturated.saturation()
    assert "at least 10 distinct tests" in saturated.saturation()
    assert "held-out check" in pred(36, 30, 24).saturation()  # 36 > 30, but 30 <= 30
    assert pred(72, 66, 24).saturation() is None  # the 12-test plan: 100 % true class
