"""Fixtures of the report tests: simulated run directories (see report_runs.py)."""

from __future__ import annotations

import pytest
from report_runs import HEADER, simulated_rows, write_run

from campaign.cli import main


@pytest.fixture(scope="session")
def rows():
    return simulated_rows()


@pytest.fixture(scope="session")
def complete_run(tmp_path_factory, rows):
    """A complete run: 5 poses x 3 repeats, one repeat of test 4 failed (saturation)."""
    rows = [dict(r) for r in rows]
    failed = rows[10]
    failed.update(status="failed", flags="saturation;retried",
                  **{c: "" for c in HEADER[13:19]})
    rows[4]["flags"] = "drift"
    rows[4]["drift_mm"] = 0.051
    return write_run(tmp_path_factory.mktemp("runs") / "complete", rows)


@pytest.fixture(scope="session")
def aborted_run(tmp_path_factory, rows):
    """An aborted run: Ctrl-C during test 5 (4 of 5 tests done, last line half written)."""
    return write_run(tmp_path_factory.mktemp("runs") / "aborted", rows[:13], status="aborted",
                     reason="interrupted by the operator (Ctrl-C)", truncate_last=True)


@pytest.fixture(scope="session")
def complete_report(complete_run, tmp_path_factory):
    """The analysis of :func:`complete_run` with its report (``--trials 10``), made once
    per session for every test that reads it (read only: copy it to change it)."""
    out = tmp_path_factory.mktemp("complete-report") / "analysis"
    assert main(["analyze", str(complete_run), "--trials", "10", "--out", str(out)]) == 0
    return out
