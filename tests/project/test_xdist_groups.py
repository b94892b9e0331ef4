"""The README's test command (pytest-xdist, ``--dist loadfile``): every file that uses a
whole-campaign session fixture is in that fixture's one-worker group of tests/conftest.py,
and the scheduler gives each group to one worker."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.conftest import CAMPAIGN_FIXTURES, SAME_WORKER

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("fixture", CAMPAIGN_FIXTURES)
def test_every_file_using_a_campaign_fixture_is_in_its_group(fixture):
    users = sorted(str(p.relative_to(ROOT)) for p in (ROOT / "tests").rglob("test_*.py")
                   if p != Path(__file__).resolve()
                   and re.search(rf"\b{fixture}\b", p.read_text(encoding="utf-8")))
    assert users and users == sorted(SAME_WORKER[fixture])


def test_the_scheduler_puts_a_group_in_one_unit_and_other_files_alone(pytestconfig):
    pytest.importorskip("xdist")
    from tests.conftest import pytest_xdist_make_scheduler

    class Config:  # the two options the scheduler reads
        def __init__(self, dist):
            self.dist = dist
            self.option = type("Option", (), {"loadscopereorder": True})()

        def getvalue(self, name):
            return self.dist

    assert pytest_xdist_make_scheduler(Config("load"), None) is None
    sched = pytest_xdist_make_scheduler(Config("loadfile"), None)
    a, b = SAME_WORKER["demo_runs"][:2]
    assert sched._split_scope(f"{a}::test_x[sqlite]") == sched._split_scope(f"{b}::test_y")
    assert sched._split_scope("tests/web/test_api.py::test_z") == "tests/web/test_api.py"


def test_every_e2e_entry_names_a_test_that_exists():
    """A renamed file or test would silently fall back into the fast lane."""
    from tests.conftest import E2E

    for entry in E2E:
        path, _, func = entry.partition("::")
        source = (ROOT / path).read_text(encoding="utf-8")
        assert not func or re.search(rf"^def {re.escape(func)}\(", source, re.M), entry
