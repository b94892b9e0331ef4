"""Distinct equations of a campaign's design, and ``--model auto`` setting aside the
classes a design cannot test (analysis/identification/models/design_size.py, select.py)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from analysis.identification.estimate import identify
from analysis.identification.models.apply import design_warnings
from analysis.identification.models.design_size import design_size, distinct_tests
from analysis.identification.models.fit import prepare
from analysis.identification.models.names import ModelChoice
from analysis.identification.models.select import select_model, supported
from analysis.identification.poses import pose_groups
from analysis.identification.studies import model_classes as mc
from analysis.model.gravity import gear_torques

RESULTS = Path(__file__).resolve().parents[1] / "studies" / "results"


def test_repeats_add_no_equation_and_load_cases_do():
    rng = np.random.default_rng(3)
    f = np.array([800.0, 0, -500, 0, 40, 0])
    g = np.array([0.0, 700, 0, 30, 0, 0])
    # pose 0: f three times (scatter 1 %), g twice; pose 1: f once, with 3 components only
    w = np.array([f, f, g, f, g, f]) * (1 + 0.01 * rng.standard_normal((6, 1)))
    group = np.array([0, 0, 0, 0, 0, 1])
    measured = np.ones((6, 6), bool)
    measured[5, 3:] = False
    assert distinct_tests(group, w).tolist() == [0, 0, 1, 0, 1, 2]
    s = design_size(group, w, measured)
    assert (s.tests, s.equations, s.equations_held_out) == (3, 15, 3)
    # the reasons: exact fit at >= the equations, underdetermined held-out at >= 3
    assert "fits the tests' means exactly" in s.untestable(15)
    assert "held-out check is underdetermined" in s.untestable(3)
    assert s.untestable(2) == ""
    # a load 10 % larger is another test (beyond the 5 % repeat scatter)
    assert distinct_tests(np.zeros(2, int), np.array([f, 1.1 * f])).tolist() == [0, 1]


def _campaign(plan_dir: str, lab, seed: int):
    robot, _, k, loads, noise = mc.shop_lab()
    tests, _ = mc.simulate(robot, lab, k, loads, 0, noise, seed, mc.plan_design(plan_dir))
    res = identify(robot, tests, "exact", noise=noise, validate=False)
    taus = (gear_torques(robot, tests.q, np.zeros(6)), gear_torques(robot, tests.q, tests.w))
    return prepare(robot, tests, res.joints, res.x, noise, "exact", taus,
                   pose_groups(tests.q, mc.HOLDOUT_RADIUS))


def test_auto_sets_aside_links_on_the_saturated_five_test_plan():
    """The protocol's 5-test shop plan (15 rows, 30 distinct equations): every class with
    links has 30 or more parameters, so auto may not choose one however low its BIC."""
    _, lab, *_ = mc.shop_lab()
    links = replace(lab, lost_motion=None, compensator=None, gravity="off")
    data = _campaign(str(RESULTS / "plan_shop_compensator+links"), links, 100)
    sel = select_model(data, ModelChoice(auto=True))
    assert (sel.design.tests, sel.design.equations) == (5, 30)
    bad = {c.name for c in sel.untestable()}
    assert bad and all("links" in n for n in bad)
    assert "links" not in sel.chosen.name and not sel.chosen.untestable
    # no testable class explains link bending: refused, not a wrong k with narrow intervals
    assert not sel.accepted and sel.chosen.chi2_nu > 10
    # a saturated class with links fits the means exactly: chi2 the repeats' scatter
    # only, a lower BIC than the joints' by far, and still not supported
    lk = min(sel.untestable(), key=lambda c: c.bic)
    joints = next(c for c in sel.candidates if c.name == "joints")
    assert lk.n_params >= 30 and lk.bic < joints.bic - 10 and not supported(lk, joints)
    (warning,) = design_warnings(sel)
    assert "5 distinct tests, 30 equations" in warning and f"{lk.name} (" in warning


def test_auto_chooses_links_on_the_planners_raised_design():
    """The planner's design for compensator+links (13 tests, the count it raised the
    protocol's 5 to): the links class is testable and chosen."""
    _, lab, *_ = mc.shop_lab()
    links = replace(lab, lost_motion=None, compensator=None, gravity="off")
    data = _campaign(str(RESULTS / "plan_shop_compensator+links_13tests"), links, 100)
    sel = select_model(data, ModelChoice(auto=True))
    assert (sel.design.tests, sel.design.equations) == (13, 78)
    assert sel.chosen.name == "links" and sel.accepted and not sel.untestable()
    assert design_warnings(sel) == ()
