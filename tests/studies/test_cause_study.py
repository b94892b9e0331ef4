"""The cause study's key claims on a few seeded campaigns (tests/studies/cause_study.py).

On the realistic arm (:mod:`analysis.kinetostatics.realistic`) with each effect alone,
5 poses x 3 loads: every campaign is refused, the true mechanism is named first and the
tool point is not; a 100 mm tool-point error is named first; clean campaigns are not
refused and each cause test fires rarely. Deterministic seeds; the full study (100
campaigns per effect) writes its table into docs/identification.md.
"""

from __future__ import annotations

import pytest

from analysis.model.robots import load_robot
from tests.studies import cause_study as cs

N = 8


@pytest.fixture(scope="module")
def robot():
    return load_robot("kr240-2")


@pytest.fixture(scope="module")
def shop():
    return cs.shop()


@pytest.mark.parametrize("effect", ["links", "lost motion", "compensator"])
def test_each_effect_is_named_first(robot, shop, effect):
    cause = cs.EFFECTS[effect][0]
    r = cs.run_effect(robot, effect, N, 5, *shop)
    assert r["refused"] == N
    assert r["first"].get(cause, 0) >= N - 1, r["first"]  # target 90 %
    assert r["first"].get("tool_point", 0) == 0
    assert r["named"]["tool_point"] == 0  # not beside the true cause either
    assert cs.misses({effect: r}) == [] or r["first"].get(cause, 0) == N - 1


def test_a_100_mm_tool_error_is_named_first(robot, shop):
    r = cs.run_effect(robot, "tool 100 mm", 5, 5, *shop)
    assert r["refused"] == 5 and r["first"] == {"tool_point": 5}


def test_clean_campaigns_are_not_refused_and_the_tests_stay_quiet(robot, shop):
    r = cs.run_effect(robot, "clean", 20, 5, *shop)
    assert r["refused"] == 0
    # at the 1 % level 0.2 firings are expected of 20 per test; 2 or more has probability 1.7 %
    assert all(v <= 1 for v in r["fired"].values()), r["fired"]


def test_the_table_goes_between_the_markers(tmp_path, monkeypatch):
    doc = tmp_path / "identification.md"
    doc.write_text(f"before\n{cs.BEGIN}\nold\n{cs.END}\nafter\n")
    monkeypatch.setattr(cs, "DOCS", doc)
    cs.write_docs("| new |")
    assert doc.read_text() == f"before\n{cs.BEGIN}\n| new |\n{cs.END}\nafter\n"
