"""Browser tests of the GUI: a real headless Chromium (Debian's ``chromium``) via Playwright.

The server runs on 127.0.0.1 in a thread; the tests open the page with the token,
move a slider with the keyboard as a user does, wait for the figures to update and
compare the numbers on the page with the job's own result for the same settings.
"""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def page(server, open_url):
    pg = open_url(server)
    pg.wait_for_selector("#row-k6", timeout=30_000)
    return pg


def _settings(page) -> dict:
    return page.evaluate("() => body()")


def _job(body: dict, workspace: Path) -> dict:
    """The job's result for the page's request body (the API's own conversion)."""
    from campaign.jobs.sensitivity import run_sensitivity
    from campaign.web.sensitivity_api import SensitivityRequest, options_from_request

    return run_sensitivity(options_from_request(SensitivityRequest(**body), workspace)).to_dict()


def _table(page) -> dict[int, dict[str, str]]:
    out = {}
    for j in range(1, 7):
        row = page.locator(f"#row-k{j}")
        out[j] = {c: row.locator(f"td.{c}").inner_text() for c in
                  ("k-true", "median", "iqr", "std", "predicted-se", "rejected")}
    return out


def _assert_page_equals_job(page, workspace: Path) -> dict:
    body = _settings(page)
    want = _job(body, workspace)
    shown = _table(page)
    for j in want["joints"]:
        cells = shown[j["joint"]]
        assert int(cells["k-true"]) == round(j["k_true_Nm_per_rad"])
        assert int(cells["median"]) == round(j["median_Nm_per_rad"])
        assert int(cells["iqr"]) == round(j["q75_Nm_per_rad"] - j["q25_Nm_per_rad"])
        assert int(cells["std"]) == round(j["std_Nm_per_rad"])
        assert int(cells["predicted-se"]) == round(j["predicted_se_Nm_per_rad"])
        assert int(cells["rejected"]) == j["rejected"]
    return body


def _move(page, key: str, presses: int, direction: str = "ArrowRight") -> None:
    """Move a slider as a user does: focus it and press the arrow keys; wait for the
    page to show the result of the last setting."""
    before = int(page.evaluate("() => document.body.dataset.updates"))
    slider = page.locator(f"#s-{key}")
    slider.focus()
    for _ in range(presses):
        slider.press(direction)
    page.wait_for_function(f"() => Number(document.body.dataset.updates) > {before}")
    _wait_shown(page)


def _wait_shown(page) -> None:
    """Wait until the figures and the table show the form's current settings."""
    page.wait_for_function("() => document.body.dataset.shown === JSON.stringify(body())")


def test_slider_moves_update_the_numbers(page, workspace):
    first = _assert_page_equals_job(page, workspace)
    assert first["n_tests"] == 10 and first["trials"] == 1000
    old = _table(page)
    _move(page, "n_tests", 5)
    body = _assert_page_equals_job(page, workspace)
    assert body["n_tests"] == 15
    assert "15 tests" in page.locator("#sens-status").inner_text()
    # more tests: the predicted standard error of every k goes down
    new = _table(page)
    for j in range(1, 7):
        assert int(new[j]["predicted-se"]) < int(old[j]["predicted-se"])
    _move(page, "translation_sigma_um", 20)
    body = _assert_page_equals_job(page, workspace)
    assert body["translation_sigma_um"] == first["translation_sigma_um"] + 20


def test_rotation_from_the_reflector_triangle(page, workspace):
    before = int(page.evaluate("() => document.body.dataset.updates"))
    page.select_option("#rotation-from", "reflectors")
    page.wait_for_function(f"() => Number(document.body.dataset.updates) > {before}")
    _wait_shown(page)
    assert page.locator("#s-rotation_sigma_urad").is_disabled()
    _move(page, "reflector_radius_mm", 4, "ArrowLeft")
    body = _assert_page_equals_job(page, workspace)
    assert "rotation_sigma_urad" not in body and body["reflector_radius_mm"] == 80


def test_method_and_plan_poses(page, workspace):
    page.select_option("#method", "wls")
    page.select_option("#poses", "plan")
    page.wait_for_timeout(300)
    before = int(page.evaluate("() => document.body.dataset.updates"))
    page.fill("#plan", "plan")
    page.press("#plan", "Tab")  # the change event, as a user leaving the field
    page.wait_for_function(f"() => Number(document.body.dataset.updates) > {before}")
    _wait_shown(page)
    assert page.locator("#sens-error").inner_text() == ""
    body = _assert_page_equals_job(page, workspace)
    assert body["method"] == "wls" and body["poses"] == "plan"
    # wls: the medians are corrected for the linearisation bias, and the page says by how
    # much, each joint's number as the job computed it
    note = page.locator("#sens-note").inner_text()
    assert note == _job(body, workspace)["note"] and note.startswith("wls fits the linearised")
    assert "k3 " in note and " %" in note


def test_model_class_select(page, workspace):
    """The model class select lists the API's classes (joints first, the default); picking
    links identifies with it: the page shows the job's numbers and its note."""
    options = page.evaluate("() => [...document.getElementById('sens-model').options]"
                            ".map((o) => o.value)")
    assert options[0] == "joints" and "links" in options
    assert _settings(page)["model"] == "joints"
    before = int(page.evaluate("() => document.body.dataset.updates"))
    page.select_option("#sens-model", "links")
    page.wait_for_function(f"() => Number(document.body.dataset.updates) > {before}")
    _wait_shown(page)
    body = _assert_page_equals_job(page, workspace)
    assert body["model"] == "links"
    assert page.locator("#sens-note").inner_text().startswith("identified with the model "
                                                               "class links")


def test_bad_wrench_is_shown_beside_the_form(page):
    page.fill("#wrench", "0,0,0,0,0,0")
    page.locator("#wrench").dispatch_event("change")
    page.wait_for_function("() => document.getElementById('sens-error').textContent !== ''")
    assert "wrench" in page.locator("#sens-error").inner_text()


def test_runs_view_lists_the_workspace(page, workspace):
    from campaign.jobs.runs import list_workspace

    (workspace / "plan" / "summary.json").write_text('{"robot": "KUKA KR240-2"}')
    (workspace / "plan" / "summary.txt").write_text("the plan in words\n")
    page.click("#tab-runs")
    page.click("#runs-refresh")  # the table was loaded with the page, before these files
    page.wait_for_selector("#runs-table tr[data-path='plan']")
    rows = page.locator("#runs-table tbody tr")
    entries = list_workspace(workspace)
    assert rows.count() == max(1, len(entries))
    for e in entries:
        row = page.locator(f"#runs-table tr[data-path='{e.path}'][data-kind='{e.kind}']")
        assert row.locator("td.status").inner_text() == e.status
    # the page's link opens the file (with the page's cookie)
    link = page.locator("#runs-table tr[data-path='plan'] td.files a", has_text="summary.txt")
    r = page.request.get(link.evaluate("a => a.href"))  # absolute, on the page's origin
    assert r.status == 200 and r.text() == "the plan in words\n"
