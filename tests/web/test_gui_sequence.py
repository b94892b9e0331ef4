"""The whole campaign through the GUI as a user, in a fresh workspace: plan a small campaign
(Plan view), acquire it on the simulated lab (Acquire view), analyse the run (Plan &
Analyze), compensate a path with the run's model (Use view). Each step's numbers on the
page equal the files its job wrote."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import pytest

from tests.web.pages import acquire_dry_run, wait_job, wait_text
from tests.web.test_plan_view import open_page  # noqa: F401  (the browser page fixture)

pytestmark = pytest.mark.timeout(180)
ROOT = Path(__file__).parents[2]


def test_plan_acquire_analyze_compensate(open_page, tmp_path):  # noqa: F811
    ws = tmp_path / "ws"
    ws.mkdir()
    shutil.copy(ROOT / "examples" / "kr240-2_path.csv", ws / "path.csv")
    page = open_page(ws)
    # ---- Plan: 4 tests of 1 repeat from few candidates
    page.fill("#pf-campaign-tests", "4")
    page.fill("#pf-campaign-repeats", "1")
    page.fill("#plan-candidates", "300")
    page.fill("#plan-name", "seq")
    page.click("#plan-run")
    wait_job(page, "plan", "done")
    plan = ws / "plans" / "seq"
    summary = json.loads((plan / "summary.json").read_text())
    assert summary["tests"] == 4
    assert page.locator("#plan-rows tbody tr").count() == 4
    # ---- Acquire: dry run, then the simulated lab at time x 200 until complete
    assert acquire_dry_run(page, "plans/seq", "run", 200) >= 4
    assert not (ws / "run").exists()  # a dry run writes nothing
    page.click("#acq-start")
    wait_text(page, "#acq-status", "complete")
    assert page.locator("#acq-done").text_content() == "4"
    meta = json.loads((ws / "run" / "metadata.json").read_text())
    assert meta["status"] == "complete"
    assert len((ws / "run" / "tests.csv").read_text().strip().splitlines()) == 1 + 4
    # ---- Analyze the run
    page.click("#tab-plan")
    page.click("#an-refresh")
    page.wait_for_function("() => [...document.querySelectorAll('#an-run option')]"
                           ".some((o) => o.value === 'run')", timeout=10_000)
    page.select_option("#an-run", "run")
    page.click("#an-run-btn")
    if wait_job(page, "analyze", "done", "error") == "error":
        # refused on this small run: accept the listed reasons, as --accept-misfit does
        assert page.locator("#an-error").inner_text() == "", page.locator("#an-error").inner_text()
        assert page.locator("#an-reasons li").count() >= 1
        page.click("#an-retry")
        wait_job(page, "analyze", "done")
    res = json.loads((ws / "run" / "analysis" / "results.json").read_text())
    assert len(res["joints_identified"]) >= 1
    for j, k, (lo, hi) in zip(res["joints_identified"], res["joint_stiffness_Nm_per_rad"],
                              res["ci95_Nm_per_rad"], strict=True):
        row = page.locator(f"#an-k{j}")  # kN m/rad, 1 decimal
        assert row.locator("td.k").inner_text() == f"{k / 1e3:.1f}"
        assert row.locator("td.lo").inner_text() == f"{lo / 1e3:.1f}"
        assert row.locator("td.hi").inner_text() == f"{hi / 1e3:.1f}"
    assert page.locator("#an-status").inner_text().startswith("run run: complete")
    model = ws / "run" / "analysis" / "model.toml"
    assert model.is_file()
    # ---- Use: compensate the example path with the run's model under a wrench
    page.click("#tab-use")  # refreshes the file lists
    model_rel = model.relative_to(ws).as_posix()
    page.wait_for_function(
        "(m) => [...document.querySelectorAll('#comp-robot option')].some((o) => o.value === m)",
        arg=model_rel, timeout=10_000)
    page.select_option("#comp-path", "path.csv")
    page.select_option("#comp-robot", model_rel)
    for name, v in zip(("fx", "fy", "fz", "mx", "my", "mz"), (300, 0, -1500, 0, 40, 0),
                       strict=True):
        page.fill(f"#comp-w-{name}", str(v))
    page.fill("#comp-out", "comp")
    page.click("#comp-run")
    page.wait_for_selector("#view-use[data-comp='done']", timeout=30_000)
    s = json.loads((ws / "comp" / "summary.json").read_text())
    rows = len((ws / "path.csv").read_text().strip().splitlines()) - 1
    assert int(page.inner_text("#comp-points")) == s["points"] == rows
    tr, rr = s["translation_m"], s["rotation_rad"]
    for sel, value in (("#comp-before-max", tr["before"]["max"]),
                       ("#comp-before-hi", tr["before_upper95_max"]),
                       ("#comp-after-max", tr["after"]["max"]),
                       ("#comp-after-hi", tr["after_upper95_max"]),
                       ("#comp-rbefore-max", rr["before"]["max"])):  # mm, mrad; 5 digits
        shown = float(page.inner_text(sel))
        assert math.isclose(shown, 1e3 * value, rel_tol=1e-4, abs_tol=1e-9), (sel, shown)
    assert tr["before"]["max"] > 0
    assert int(page.inner_text("#comp-worst")) == s["worst_point"]["line"]
    # the page ran the job on the run's model and the wrench typed: the job itself agrees
    from campaign.jobs.compensate import CompensateOptions, run

    mine = run(CompensateOptions(robot=str(model), path=ws / "path.csv", out=ws / "comp-job",
                                 wrench_N_Nm=[300, 0, -1500, 0, 40, 0]))
    assert mine.summary["points"] == s["points"]
    assert math.isclose(mine.summary["translation_m"]["before"]["max"], tr["before"]["max"],
                        rel_tol=1e-12)
    assert mine.summary["worst_point"] == s["worst_point"]
