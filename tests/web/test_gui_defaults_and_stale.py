"""The page in Chromium: it starts from the command line's defaults, Enter runs a form's
action, and a request that fails leaves none of the previous request's results shown."""

from __future__ import annotations

import pytest

from tests.web.pages import wait_job
from tests.web.test_plan_view import demo_ws, open_page  # noqa: F401  (fixtures)

pytestmark = pytest.mark.timeout(300)


def test_the_page_starts_from_the_command_lines_defaults(open_page, workspace):  # noqa: F811
    page = open_page(workspace)
    page.wait_for_function("() => document.getElementById('an-method').options.length > 0"
                           " && document.getElementById('method').options.length > 0"
                           " && document.getElementById('plan-candidates').value !== ''")
    assert page.input_value("#an-method") == "exact"  # campaign analyze --method
    assert page.input_value("#an-robust") == "none"
    assert page.input_value("#method") == "exact"  # campaign robustness --method
    assert page.input_value("#plan-candidates") == "10000"  # campaign plan --candidates
    assert [o for o in page.locator("#an-method option").all_inner_texts()] == \
        ["ols (the paper's)", "wls", "exact (nonlinear)"]


def test_enter_in_a_field_runs_the_forms_action(open_page, workspace):  # noqa: F811
    page = open_page(workspace)
    # a fresh workspace: Acquire offers the directory Plan writes, not a "plan" that is not there
    assert page.input_value("#acq-plan") == "plans/plan-gui"
    page.fill("#plan-name", "mine")
    page.fill("#pf-campaign-tests", "4")
    page.fill("#plan-candidates", "300")
    page.press("#plan-seed", "Enter")
    assert wait_job(page, "plan", "done", "error") == "done"
    assert (workspace / "plans" / "mine" / "plan.csv").is_file()
    assert page.input_value("#acq-plan") == "plans/mine"  # the plan just written


def test_a_refused_plan_leaves_no_previous_results(open_page, workspace):  # noqa: F811
    page = open_page(workspace)
    page.fill("#pf-campaign-tests", "4")
    page.fill("#plan-candidates", "300")
    page.click("#plan-run")
    wait_job(page, "plan", "done")
    assert page.locator("#plan-rows tbody tr").count() == 4
    page.fill("#pf-campaign-tests", "0")
    page.check("#plan-force")
    page.click("#plan-run")
    wait_job(page, "plan", "error")
    assert page.locator("[data-key='campaign.tests'] .pv-msg").inner_text() != ""
    assert page.locator("#plan-rows tbody tr").count() == 0
    assert page.locator("#plan-se tbody tr").count() == 0
    assert page.evaluate("() => Object.keys(pv.plots).length") == 0


def test_a_refused_save_and_plan_names_the_replace_box(open_page, workspace):  # noqa: F811
    page = open_page(workspace)
    page.fill("#pf-campaign-tests", "4")
    page.fill("#plan-candidates", "300")
    page.click("#plan-run")
    wait_job(page, "plan", "done")
    page.click("#plan-run")
    wait_job(page, "plan", "error")
    shown = page.locator("[data-key='name'] .pv-msg").inner_text()
    assert "\u201cReplace a protocol and plan of this name\u201d" in shown, shown
    assert "--force" not in shown


def test_a_failed_analysis_leaves_no_previous_verdict(open_page, demo_ws):  # noqa: F811
    page = open_page(demo_ws)
    page.select_option("#an-run", "run")
    page.select_option("#an-method", "wls")
    page.check("#an-force")
    page.check("#an-accept")
    page.click("#an-run-btn")
    assert wait_job(page, "analyze", "done", "error", timeout=120_000) == "done"
    assert page.locator("#an-verdict").inner_text() != ""
    assert page.locator("#an-k tbody tr").count() >= 1
    page.uncheck("#an-force")  # the run has an analysis: refused without "Re-analyse"
    page.click("#an-run-btn")
    assert wait_job(page, "analyze", "error", "done", timeout=120_000) == "error"
    assert "Re-analyse" in page.locator("#an-error").inner_text()
    assert page.locator("#an-verdict").inner_text() == ""
    assert page.locator("#an-k tbody tr").count() == 0
    assert page.locator("#an-links a").count() == 0
    assert page.locator("#an-plots").is_hidden()


def test_numbers_that_round_to_zero_have_no_sign(open_page, workspace):  # noqa: F811
    page = open_page(workspace)
    assert page.evaluate("() => [pvText(-0.04, 1), pvText(-0.06, 1), pvText(-0.0, 2),"
                         " pvText(0.04, 1), pvText(-12.345, 1)]") == \
        ["0.0", "-0.1", "0.00", "0.0", "-12.3"]


def test_a_refused_sensitivity_request_hides_the_previous_figures(server, open_url):
    """An unknown robot: the figures, the table and the timing line were the previous
    settings'; they are hidden until a request succeeds again."""
    page = open_url(server)
    page.wait_for_selector("#row-k6", timeout=60_000)
    shown = "() => document.body.dataset.shown === JSON.stringify(body())"
    page.wait_for_function(shown, timeout=60_000)
    assert "trials" in page.locator("#sens-status").inner_text()
    page.fill("#robot", "kr999")
    page.dispatch_event("#robot", "change")
    page.wait_for_function("() => document.body.dataset.shown === 'error:' + "
                           "JSON.stringify(body())", timeout=60_000)
    assert "robot" in page.locator("#sens-error").inner_text()
    assert page.locator("#sens-status").inner_text() == ""
    assert page.locator("#sens-figures").is_hidden() and page.locator("#sens-table").is_hidden()
    page.fill("#robot", "kr240-2")
    page.dispatch_event("#robot", "change")
    page.wait_for_function(shown, timeout=60_000)
    assert page.locator("#sens-figures").is_visible() and page.locator("#row-k6").is_visible()


def test_every_view_fits_a_phone(browser, server):
    """At 390 px no view is wider than the window (was: Sensitivity 1,174 px, Acquire 736):
    the fields stack, the figures are drawn at the window's width, a wide table scrolls in
    its own box."""
    context = browser.new_context(viewport={"width": 390, "height": 800})
    try:
        page = context.new_page()
        page.goto(server)
        page.wait_for_selector("#row-k6", timeout=60_000)
        assert page.evaluate("() => document.documentElement.scrollWidth") <= 390
        for fig in ("fig-sets", "fig-spread", "fig-curve"):
            box = page.locator(f"#{fig} canvas").bounding_box()
            assert box is not None and box["x"] + box["width"] <= 390, (fig, box)
        # the views have built their forms (the Plan form from the schema, Use's lists)
        page.wait_for_function("() => document.body.dataset.planview === 'ready'")
        page.wait_for_selector("#view-use[data-ready='1']", state="attached")
        for view in ("acquire", "use", "plan", "runs"):
            page.click(f"#tab-{view}")
            page.wait_for_selector(f"#view-{view}", state="visible")
            assert page.evaluate("() => document.documentElement.scrollWidth") <= 390, view
    finally:
        context.close()


def test_a_tab_click_right_after_load_is_not_lost(browser, server):
    """The page's first requests held back (/openapi.json): a tab clicked meanwhile opens
    its view (its listener does not wait for them)."""
    context = browser.new_context()
    held = []
    try:
        page = context.new_page()
        page.route("**/openapi.json", lambda route: held.append(route))
        page.goto(server)
        page.click("#tab-runs")
        assert page.locator("#view-runs").is_visible()
        assert page.locator("#view-sensitivity").is_hidden()
        assert held  # the test ran while the page still waited for its routes
        for route in held:
            route.continue_()
    finally:
        context.close()
