"""Job refusals in the GUI's terms in Plan & Analyze: the API's refusal records carry
``options`` (command-line option -> request field, campaign.web.job_errors) and the page
names the field by its label, with the helper app.js shares with the Use view."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.web.conftest import post_followed
from tests.web.pages import wait_job
from tests.web.test_plan_view import _followed, demo_ws, open_page  # noqa: F401

pytestmark = pytest.mark.timeout(180)
FORCE_LABEL = "Re-analyse (replace RUN/analysis)"


def _analyse_once(ws: Path) -> None:
    if not (ws / "run" / "analysis" / "results.json").is_file():
        r = _followed(ws).post("/api/jobs/analyze", json={
            "run_dir": "run", "method": "wls", "accept_misfit": True, "report": False})
        assert r.status_code == 200, r.text


def test_analyze_refusal_names_its_options(demo_ws):  # noqa: F811
    _analyse_once(demo_ws)
    r = _followed(demo_ws).post("/api/jobs/analyze", json={"run_dir": "run", "method": "wls"})
    assert r.status_code == 400
    d = r.json()
    assert "--force" in d["detail"] and d["options"]["--force"] == "force"


def test_plan_refusal_names_its_options(client):
    # the form sends no weights: the planner's refusal names --weights, the field weights
    r = post_followed(client, "/api/plan/run", json={"strategy": "weighted", "candidates": 100,
                                           "name": "pw"})
    assert r.status_code == 400, r.text
    d = r.json()
    assert "--weights" in d["detail"] and d["options"] == {"--weights": "weights"}


def test_page_says_the_checkbox_label_not_the_cli_option(open_page, demo_ws):  # noqa: F811
    _analyse_once(demo_ws)
    page = open_page(demo_ws)
    assert page.locator("#an-form [data-field=force]").get_attribute("data-label") == FORCE_LABEL
    page.select_option("#an-run", "run")
    page.select_option("#an-method", "wls")
    page.uncheck("#an-force")
    page.click("#an-run-btn")
    wait_job(page, "analyze", "error")
    text = page.locator("#an-error").inner_text()
    assert f"\u201c{FORCE_LABEL}\u201d" in text and "--force" not in text, text
    assert "output directory exists" in text
    # the output folder has no field in the form: named in words, not as --out
    assert "--out" not in text and "\u201cOutput folder\u201d run" in text, text
