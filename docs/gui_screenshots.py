"""Take the screenshots of docs/gui.md of ``campaign gui`` (system Chromium via Playwright).

Usage: ``python docs/gui_screenshots.py WORKSPACE`` with a workspace holding a plan,
a run and an analysis (``campaign demo --out WORKSPACE``); writes
``docs/gui_sensitivity.png``, ``docs/gui_runs.png``, ``docs/gui_use.png`` (the Use view:
K_X at a pose and the compensation of ``examples/kr240-2_path.csv``, copied into the
workspace as ``kr240-2_path.csv`` when it is not there) and ``docs/gui_plan.png`` (the
Plan & Analyze view after a plan and a re-analysis of the workspace's run ``run``) and
``docs/gui_acquire.png`` (the Acquire view after a dry run, during an acquisition of
the workspace's plan ``plan`` on the simulated lab, time x 50, into
``acquire-screenshot``: two poses done, the next one settling under its load).

``python docs/gui_screenshots.py WORKSPACE VIEW ...`` takes only those views' screenshots
(names: sensitivity, runs, use, plan, acquire).
"""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.web.pages import (  # noqa: E402  (the browser tests' waits)
    acquire_dry_run,
    wait_job,
    wait_text,
    wait_use_shown,
)

VIEWS = ("sensitivity", "runs", "use", "plan", "acquire")


def main(workspace: str, views: tuple[str, ...] = VIEWS) -> None:
    from playwright.sync_api import sync_playwright

    from campaign.web.server import GuiOptions, make_server, url_of

    token = "screenshot-token-0123456789"
    srv, sock = make_server(GuiOptions(workspace=Path(workspace), port=0), token)
    threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True).start()
    while not srv.started:
        time.sleep(0.01)
    docs = Path(__file__).resolve().parent
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path="/usr/bin/chromium", args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1240, "height": 980})
        page.goto(url_of(sock, token))
        page.wait_for_selector("#row-k6")
        if "sensitivity" in views:
            slider = page.locator("#s-n_tests")
            slider.focus()
            for _ in range(5):
                slider.press("ArrowRight")
            page.wait_for_function(
                "() => document.body.dataset.shown === JSON.stringify(body())")
            page.screenshot(path=docs / "gui_sensitivity.png", full_page=True)
        if "runs" in views:
            page.click("#tab-runs")
            page.wait_for_selector("#runs-table")
            page.set_viewport_size({"width": 1240, "height": 430})
            page.screenshot(path=docs / "gui_runs.png")
        if "use" in views:
            use_view(page, Path(workspace), docs)
        if "plan" in views:
            _plan_and_analyze(page, docs)
        if "acquire" in views:
            _acquire(page, docs)
        browser.close()
    srv.should_exit = True


def use_view(page, workspace: Path, docs: Path) -> None:
    """The Use view: one slider move, the deflection along the example path, a placement
    search of the example workpiece, then the compensation of the example path."""
    import shutil

    for name in ("kr240-2_path.csv", "part_circle.csv"):
        if not (workspace / name).exists():
            shutil.copy(docs.parent / "examples" / name, workspace / name)
    page.set_viewport_size({"width": 1240, "height": 980})
    page.click("#tab-use")
    page.wait_for_selector("#view-use[data-ready='1']")
    models = page.eval_on_selector_all("#use-robot option", "os => os.map(o => o.value)")
    model = next((m for m in models if m.endswith("model.toml")), None)
    if model:
        page.select_option("#use-robot", model)
        page.wait_for_function("(m) => document.getElementById('use-robot-info')"
                               ".textContent.includes('model.toml')", arg=model)
    slider = page.locator("#q2")
    slider.focus()
    for _ in range(4):
        slider.press("ArrowRight")
    wait_use_shown(page)
    page.select_option("#pd-path", "kr240-2_path.csv")
    if model:
        page.select_option("#pd-robot", model)
    page.click("#pd-run")
    page.wait_for_selector("#view-use[data-pd='done']", timeout=60_000)
    page.select_option("#pl-path", "part_circle.csv")
    page.select_option("#pl-robot", "kr240-2")
    for field, value in (("x_step_mm", "50"), ("y_step_mm", "50"), ("config", "-1,-1,-1"),
                         ("workers", "0"), ("out", "placement-screenshot")):
        page.fill(f"#pl-{field}", value)
    page.check("#pl-force")
    page.click("#pl-run")
    page.wait_for_selector("#view-use[data-place='done']", timeout=120_000)
    page.select_option("#comp-path", "kr240-2_path.csv")
    if model:
        page.select_option("#comp-robot", model)
    page.fill("#comp-out", "compensation-screenshot")
    page.check("#comp-force")
    page.click("#comp-run")
    page.wait_for_selector("#view-use[data-comp='done']", timeout=60_000)
    page.screenshot(path=docs / "gui_use.png", full_page=True)


def _plan_and_analyze(page, docs: Path) -> None:
    page.set_viewport_size({"width": 1240, "height": 980})
    page.click("#tab-plan")
    wait_job(page, "planview", "ready", timeout=30_000)
    page.check("#plan-compact")  # the keys with a value (the form has every key)
    page.fill("#plan-candidates", "1000")
    page.click("#plan-run")
    wait_job(page, "plan", "done", timeout=120_000)
    page.wait_for_function("() => pv.plots['plan-map-fig'] !== undefined")
    if page.locator("#an-run option[value='run']").count():
        page.select_option("#an-run", "run")
        page.select_option("#an-method", "wls")
        page.check("#an-force")
        page.evaluate("() => { document.getElementById('an-plots').dataset.ready = ''; }")
        page.click("#an-run-btn")
        wait_job(page, "analyze", "done", "error", timeout=180_000)
        # the residual and validation plots of that analysis
        page.wait_for_function("() => document.getElementById('an-plots').dataset.ready",
                               timeout=30_000)
    page.screenshot(path=docs / "gui_plan.png", full_page=True)


def _acquire(page, docs: Path) -> None:
    """The Acquire view: a dry run, then the workspace's plan on the simulated lab (x 50,
    slow enough to catch a test settling under its load)."""
    page.set_viewport_size({"width": 1240, "height": 980})
    acquire_dry_run(page, "plan", "acquire-screenshot", 50)
    page.click("#acq-start")
    # mid-run: poses 1 and 2 done on the zone map, pose 3 being measured under its load
    page.wait_for_function(
        "() => (document.getElementById('acq-map').dataset.done || '') === '1,2'"
        " && document.getElementById('acq-map').dataset.current"
        " && document.querySelector('#acq-stage').textContent === 'settle'"
        " && Number(document.getElementById('acq-trace-readings').textContent) >= 3",
        timeout=300_000, polling=20)
    page.screenshot(path=docs / "gui_acquire.png", full_page=True)
    wait_text(page, "#acq-status", "complete", timeout=300_000)


if __name__ == "__main__":
    unknown = set(sys.argv[2:]) - set(VIEWS)
    if len(sys.argv) < 2 or unknown:
        sys.exit(f"usage: gui_screenshots.py WORKSPACE [VIEW ...] with VIEW in {VIEWS}")
    main(sys.argv[1], tuple(sys.argv[2:]) or VIEWS)
