"""The Acquire view after Resume: the run is running again, so the reason it stopped
(the Abort button's, kept in metadata.json until the run ends) is not shown beside
'running'."""

from __future__ import annotations

import pytest

from tests.web.pages import acquire_dry_run, wait_text
from tests.web.test_acquire_view import plan_dir, workspace  # noqa: F401  (fixtures)

pytestmark = pytest.mark.timeout(150)


def test_resumed_run_shows_no_stop_reason(server, workspace, open_url):  # noqa: F811
    page = open_url(server)
    assert acquire_dry_run(page, "plan", "run", 10) >= 3
    page.click("#acq-start")
    wait_text(page, "#acq-stage", "load", "settle", "measure", timeout=30_000)
    page.click("#acq-abort")
    wait_text(page, "#acq-status", "aborted")
    reason = page.locator("#acq-reason").text_content()
    assert "(Abort)" in reason and "Ctrl-C" not in reason, reason  # the page's word
    page.click("#acq-resume")
    wait_text(page, "#acq-running", "running", timeout=30_000)
    page.wait_for_timeout(300)  # a state read after the start
    if page.locator("#acq-running").text_content() == "running":
        assert page.locator("#acq-reason").text_content() == ""
    wait_text(page, "#acq-status", "complete", timeout=90_000)
    assert page.locator("#acq-reason").text_content() == ""
    assert page.locator("#acq-done").text_content() == "3"


def test_start_into_a_used_run_directory_is_refused_in_the_views_words(
        server, workspace, open_url):  # noqa: F811
    """The refusal names the view's field and button, not --out and --resume."""
    (workspace / "used").mkdir()
    (workspace / "used" / "tests.csv").write_text("test_id\n")
    page = open_url(server)
    assert acquire_dry_run(page, "plan", "used", 10) >= 3
    page.click("#acq-start")
    page.wait_for_function("() => document.getElementById('acq-error').textContent !== ''")
    text = page.locator("#acq-error").text_content()
    assert "run directory exists and is not empty" in text, text
    assert "\u201cResume\u201d" in text and "\u201cNew run directory\u201d" in text, text
    assert "--" not in text, text
