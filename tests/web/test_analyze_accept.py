"""Accepting a refusal in the Analyze view accepts that refusal only, as the command line's
``--accept-misfit`` accepts one invocation: the next analysis (another run, method or
robust fit) is refused again when its data do not support it, and "Re-analyse" (the CLI's
``--force``) does not carry over to another run's analysis."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.web.conftest import copy_acquired
from tests.web.pages import wait_job
from tests.web.test_plan_view import open_page  # noqa: F401  (the browser page fixture)

pytestmark = pytest.mark.timeout(240)


@pytest.fixture(scope="module")
def runs(tmp_path_factory, acquired_kr240) -> Path:
    """A workspace: ``run`` (6 KR240-2 tests on the simulated lab, analysed, ols), and
    ``bad``, ``bad2``: copies of it with a gross error (dx of test 3 +0.5 mm), not
    analysed; the analysis refuses them (misfit)."""
    import pandas as pd

    from campaign.jobs.analyze import AnalyzeOptions
    from campaign.jobs.analyze import run as analyze
    from campaign.jobs.choices import Method

    ws = copy_acquired(acquired_kr240, tmp_path_factory.mktemp("accept-ws"))
    for name in ("bad", "bad2"):
        shutil.copytree(ws / "run", ws / name, ignore=shutil.ignore_patterns("*.parquet"))
        tests = pd.read_csv(ws / name / "tests.csv")
        tests.loc[2, "dx_mm"] += 0.5
        tests.to_csv(ws / name / "tests.csv", index=False)
    analyze(AnalyzeOptions(run_dir=ws / "run", method=Method("ols"), report=False))
    return ws


def _analyze(page, run: str) -> str:
    page.select_option("#an-run", run)
    page.click("#an-run-btn")
    return wait_job(page, "analyze", "done", "error", timeout=120_000)


def test_an_accepted_refusal_does_not_accept_the_next(open_page, runs):  # noqa: F811
    page = open_page(runs)
    assert _analyze(page, "bad") == "error"
    reasons = page.locator("#an-reasons li").all_inner_texts()
    assert reasons and reasons[0].startswith("misfit:")
    assert not (runs / "bad" / "analysis").exists()
    page.click("#an-retry")
    wait_job(page, "analyze", "done", timeout=120_000)
    res = json.loads((runs / "bad" / "analysis" / "results.json").read_text())
    assert res["misfit_accepted"] == {"accepted": True, "problems": reasons}
    assert "ACCEPTED DESPITE A REFUSAL" in page.locator("#an-verdict").inner_text()
    # the acceptance was for that refusal: the box the user did not tick stays unticked
    assert not page.locator("#an-accept").is_checked()
    # another run with the same fault: refused again, nothing written
    assert _analyze(page, "bad2") == "error"
    assert page.locator("#an-refused").is_visible()
    assert page.locator("#an-reasons li").count() >= 1
    assert not (runs / "bad2" / "analysis").exists()
    # the analysed run: not replaced unless "Re-analyse" is ticked for it
    before = (runs / "run" / "analysis" / "results.json").read_bytes()
    assert _analyze(page, "run") == "error"
    assert "Re-analyse" in page.locator("#an-error").inner_text()
    assert (runs / "run" / "analysis" / "results.json").read_bytes() == before
    # re-analysing the accepted run (same data, "Re-analyse" ticked): refused again, as the
    # command line without --accept-misfit; the accepted result stays on disk
    page.select_option("#an-run", "bad")
    page.check("#an-force")
    page.click("#an-run-btn")
    assert wait_job(page, "analyze", "done", "error", timeout=120_000) == "error"
    assert page.locator("#an-reasons li").all_inner_texts() == reasons
    res = json.loads((runs / "bad" / "analysis" / "results.json").read_text())
    assert res["misfit_accepted"]["accepted"] is True
