"""The Use view's queued and new parts in a real headless Chromium: the sliders in the
pendant convention, the deflection along a path with its band (workspace file or upload),
and the placement search with its progress bar, its cancellation, a full queue and a
bound exceeded.

The user clicks, types and moves sliders with the keyboard; the numbers on the page are
compared with the jobs' own results (campaign.jobs.stiffness, path_deflection, compensate,
place) for the same inputs.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from campaign.web.job_process import CANCEL_GRACE
from tests.web.conftest import browser_page, gui_server

ROOT = Path(__file__).parents[2]
TOKEN = "use-jobs-token-0123456789"
#: how long a cancelled job may take to end (ms): the server gives its process CANCEL_GRACE
#: s to reach its next progress report before terminating it, then waits for it to end;
#: a bound on the job's state, never a wait in its own right (a loaded machine takes long)
CANCEL_BOUND_MS = int((CANCEL_GRACE + 90) * 1000)
WRENCH = [500.0, 0.0, -1000.0, 0.0, 20.0, 0.0]  # the page's default along a path
#: the search of the tests (441 placements, about 2 s in the server's process)
BOX = {"x_mm": "1400..1800", "y_mm": "-200..200", "z_mm": "200", "x_step_mm": "20",
       "y_step_mm": "20", "tool_angle_step_deg": "30", "config": "-1,-1,-1", "workers": "0"}


@pytest.fixture(scope="module")
def ws(tmp_path_factory, analyses) -> Path:
    """A workspace with the example path, the example workpiece and an analysis A (the
    session's :func:`~tests.conftest.analyses`)."""
    a = analyses[0]
    ws = tmp_path_factory.mktemp("use-jobs") / "ws"
    ws.mkdir()
    shutil.copy(ROOT / "examples" / "kr240-2_path.csv", ws / "path.csv")
    shutil.copy(ROOT / "examples" / "part_circle.csv", ws / "part.csv")
    shutil.copytree(a, ws / "A")
    return ws


@pytest.fixture(scope="module")
def page(browser, ws):
    # the page is the point here: its jobs run in the queue's threads (no process start-up
    # per job); the processes are tested over HTTP in test_jobs_queue.py
    with gui_server(ws, TOKEN, jobs_in_threads=True) as url, browser_page(browser, url) as pg:
        pg.wait_for_selector("#view-use[data-ready='1']", state="attached", timeout=30_000)
        pg.click("#tab-use")
        pg.wait_for_selector("#view-use", state="visible")
        yield pg


def _close(shown: str, value: float, rel: float = 1e-4) -> None:
    assert math.isclose(float(shown.strip()), value, rel_tol=rel, abs_tol=1e-9), (shown, value)


def _settled(page) -> list[float]:
    """The model-convention joints (deg) once the page shows the job's answer for them."""
    js = ("() => { const v = document.getElementById('view-use');"
          " return !v.dataset.busy && v.dataset.shownQ === JSON.stringify(useView.poseDeg()); }")
    page.wait_for_function(js, timeout=20_000)
    page.wait_for_timeout(150)
    page.wait_for_function(js)
    return json.loads(page.get_attribute("#view-use", "data-shown-q"))


def test_pendant_sliders_show_the_jobs_numbers_and_keep_the_limits(page, ws):
    from analysis.model.robots import load_robot
    from campaign.jobs.stiffness import StiffnessOptions, run

    robot = load_robot("kr240-2")
    page.check("#use-pendant-mode")
    assert "pendant convention" in page.inner_text("#use-joints-legend")
    q0 = _settled(page)
    a2 = page.locator("#q2")
    a2.focus()
    for _ in range(4):
        a2.press("ArrowRight")  # A2 +2 deg on the pendant: q2 -2 deg (sign -1)
    q = _settled(page)
    pendant = [float(page.input_value(f"#q{j}-deg")) for j in range(1, 7)]
    assert np.allclose(np.degrees(robot.from_controller(np.radians(pendant))), q, atol=1e-9)
    assert q[1] == pytest.approx(q0[1] - 2.0)
    res = run(StiffnessOptions(robot="kr240-2", q_rad=np.radians(q).tolist(),
                               wrench_N_Nm=[0, 0, -2000, 0, 200, 0]))
    _close(page.inner_text("#use-kx-t-22"), res.K_X[2][2] / 1e3)
    _close(page.inner_text("#use-d-dz"), 1e3 * res.deflection_nonlinear_m_rad[2])
    shown = [float(v) for v in re.findall(r"q\d (-?[\d.]+)", page.inner_text("#use-pendant"))]
    assert np.allclose(shown, q, rtol=1e-4)  # the other convention: the model's q
    # the pendant's A3 = -q3 - 90 deg: its End is the model's lower limit of q3
    a3 = page.locator("#q3")
    a3.focus()
    a3.press("End")
    for _ in range(3):
        a3.press("ArrowRight")
    q = _settled(page)
    assert q[2] == pytest.approx(math.degrees(robot.lower[2]), abs=1e-6)
    box = page.locator("#q1-deg")  # typed past the limit: held at it
    box.fill("-999")
    box.press("Enter")
    assert "held at its limit" in page.inner_text("#use-limit")
    q = _settled(page)
    assert q[0] == pytest.approx(math.degrees(robot.upper[0]), abs=1e-6)
    assert page.inner_text("#use-error") == ""
    page.uncheck("#use-pendant-mode")  # back to the model's q: the same pose
    assert _settled(page) == pytest.approx(q)
    assert float(page.input_value("#q1-deg")) == pytest.approx(q[0])


def test_deflection_along_a_path_with_its_band(page, ws):
    from campaign.jobs.compensate import CompensateOptions
    from campaign.jobs.compensate import run as compensate
    from campaign.jobs.path_deflection import PathDeflectionOptions, run

    page.click("#tab-use")
    page.select_option("#pd-path", "path.csv")
    page.select_option("#pd-robot", "A/model.toml")
    page.click("#pd-run")
    page.wait_for_selector("#view-use[data-pd='done']", timeout=30_000)
    mine = run(PathDeflectionOptions(robot=str(ws / "A/model.toml"), path=ws / "path.csv",
                                     wrench_N_Nm=WRENCH))
    assert int(page.inner_text("#pd-points")) == mine.line.size
    _close(page.inner_text("#pd-max"), 1e3 * float(mine.norm_p.max()))
    _close(page.inner_text("#pd-max-hi"), 1e3 * float(mine.norm_p_hi.max()))
    assert int(page.inner_text("#pd-worst")) == int(mine.line[np.argmax(mine.norm_p)])
    # the plot: every point, and the band equal to the compensation's own prediction
    comp = compensate(CompensateOptions(robot=str(ws / "A/model.toml"), path=ws / "path.csv",
                                        out=ws / "comp-check", wrench_N_Nm=WRENCH))
    import pandas as pd

    table = pd.read_csv(comp.files[0])
    data = page.evaluate("() => useView.state.pdPlot.data")
    assert data[0] == mine.line.tolist()
    assert np.allclose(data[1], table["dx_mm"], rtol=1e-9)
    assert np.allclose(data[2], table["dx_hi95_mm"], rtol=1e-9)
    assert np.allclose(data[3], table["dx_lo95_mm"], rtol=1e-9)
    assert not (ws / ".gui" / "uploads").exists() or not any((ws / ".gui" / "uploads").iterdir())
    # an uploaded file with a bad value: the reader's file:line message, by the file's name
    lines = (ws / "path.csv").read_text().splitlines()
    head = lines[0].split(",")
    cells = lines[4].split(",")
    cells[head.index("q3_deg")] = "x"
    lines[4] = ",".join(cells)
    page.set_input_files("#pd-file", files=[{"name": "bad.csv", "mimeType": "text/csv",
                                             "buffer": ("\n".join(lines) + "\n").encode()}])
    page.click("#pd-run")
    page.wait_for_selector("#view-use[data-pd='error']", timeout=30_000)
    assert page.inner_text("#pd-error") == \
        "bad.csv:5 (point 4): column q3_deg: 'x' is not a finite number"
    assert not any((ws / ".gui" / "uploads").iterdir())
    page.set_input_files("#pd-file", files=[])


def _fill_place(page, values: dict) -> None:
    page.select_option("#pl-path", "part.csv")
    page.select_option("#pl-robot", "kr240-2")
    for field, value in values.items():
        page.fill(f"#pl-{field}", value)


def test_placement_search_with_progress_equals_the_place_job(page, ws):
    from campaign.jobs.place import PlaceOptions, run

    _fill_place(page, {**BOX, "out": "placed"})
    page.click("#pl-run")
    page.wait_for_selector("#view-use[data-place='done']", timeout=60_000)
    assert page.evaluate("() => document.getElementById('pl-progress').value") == 1
    doc = json.loads((ws / "placed" / "placement.json").read_text())
    p = doc["placement"]
    for key, name in (("x_mm", "x"), ("y_mm", "y"), ("z_mm", "z"), ("yaw_deg", "yaw")):
        _close(page.inner_text(f"#pl-best-{name}"), p[key], 1e-6)
    _close(page.inner_text("#pl-best-objective"), doc["objective"])
    _close(page.inner_text("#pl-best-nonlinear"), doc["objective_nonlinear"])
    assert int(page.inner_text("#pl-best-placements")) == doc["search_space"]["placements"] == 441
    assert int(page.inner_text("#pl-best-infeasible")) == doc["infeasible"]["count"]
    for i, r in enumerate(doc["runner_ups"], 1):
        cell = page.inner_text(f"#pl-runner-{i} .obj")
        _close(cell.split()[0], r["objective"])
        assert r["objective"] >= doc["objective"]
    # the job itself, with the same options, finds the same placement
    mine = run(PlaceOptions(robot="kr240-2", path=ws / "part.csv", out=ws / "place-job",
                            x_mm="1400..1800", y_mm="-200..200", z_mm="200", x_step_mm=20,
                            y_step_mm=20, tool_angle_step_deg=30, config="-1,-1,-1",
                            workers=0)).placement
    assert mine["placement"] == doc["placement"] and mine["objective"] == doc["objective"]
    assert "--" not in page.inner_text("#pl-best")  # its warnings name this form's fields
    hrefs = page.eval_on_selector_all("#pl-files a", "els => els.map(a => a.textContent)")
    assert "placed/placement.json" in hrefs


def test_cancel_leaves_no_files(page, ws, monkeypatch):
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    from campaign.web.job_queue import Progress

    # Under load this test saw 'done', never 'cancelled': the page kept the previous
    # search's data-place-fraction (1) and id, so the wait below ended at once and Cancel
    # deleted the previous, finished job (use.js now clears both when a search starts,
    # and sends a Cancel clicked before the job's id once the id comes). And the job (in
    # the server's threads here) holds at its first report of a fraction in (0, 1) until
    # the cancellation is recorded, so the search cannot end before the cancel is served.
    reported = Progress.report

    def report_then_hold(self, fraction, text):
        reported(self, fraction, text)
        if fraction is not None and 0 < fraction < 1:
            end = time.monotonic() + CANCEL_BOUND_MS / 1000  # a bound, not a wait
            while not self.cancelled() and time.monotonic() < end:
                time.sleep(0.01)

    monkeypatch.setattr(Progress, "report", report_then_hold)
    _fill_place(page, {**BOX, "x_step_mm": "5", "y_step_mm": "5", "out": "cancelled/run"})
    page.click("#pl-run")
    page.wait_for_function("() => Number(document.getElementById('view-use').dataset"
                           ".placeFraction) > 0", timeout=120_000)
    page.click("#pl-cancel")
    # the page shows 'cancelled' once the job's state is (a bound beyond the server's own)
    try:
        page.wait_for_selector("#view-use[data-place='cancelled']", state="attached",
                               timeout=CANCEL_BOUND_MS)
    except PlaywrightTimeout:
        shown = page.evaluate("() => [document.getElementById('view-use').dataset.place, "
                              "document.getElementById('pl-text').textContent, "
                              "document.getElementById('pl-error').textContent]")
        raise AssertionError(f"not cancelled: data-place, text, error = {shown}") from None
    assert "cancelled" in page.inner_text("#pl-text")
    assert not (ws / "cancelled").exists()
    assert page.is_enabled("#pl-run")


def test_a_full_queue_and_a_bound_show_their_messages(page, ws):
    # three long searches fill the queue (one runs, two wait)
    ids = page.evaluate("""async (box) => {
      const s = await (await fetch('/api/session')).json();
      const ids = [];
      for (const out of ['q1', 'q2', 'q3']) {
        const r = await fetch('/api/jobs/place', { method: 'POST', headers: {
          'Content-Type': 'application/json', [s.csrf_header]: s.csrf_token },
          body: JSON.stringify({ ...box, out }) });
        ids.push([r.status, (await r.json()).id]);
      }
      return ids; }""", {"robot": "kr240-2", "path": "part.csv", "x_mm": "1400..1800",
                         "y_mm": "-200..200", "z_mm": "200", "x_step_mm": 5, "y_step_mm": 5,
                         "tool_angle_step_deg": 30, "config": "-1,-1,-1", "workers": 0})
    try:
        assert [s for s, _ in ids] == [202, 202, 202]
        _fill_place(page, {**BOX, "out": "fourth"})
        page.click("#pl-run")
        page.wait_for_selector("#view-use[data-place='error']", timeout=30_000)
        assert page.inner_text("#pl-error").startswith("the job queue is full (1 running, "
                                                       "2 waiting")
    finally:
        page.evaluate("""async (ids) => {
          const s = await (await fetch('/api/session')).json();
          for (const id of ids) await fetch('/api/jobs/' + id, { method: 'DELETE',
            headers: { [s.csrf_header]: s.csrf_token } }); }""", [i for _, i in ids])
    for _, job_id in ids:
        end = time.monotonic() + CANCEL_BOUND_MS / 1000
        while time.monotonic() < end:
            state = page.evaluate("async (id) => (await (await fetch('/api/jobs/' + id))"
                                  ".json()).state", job_id)
            if state == "cancelled":
                break
            time.sleep(0.1)
        assert state == "cancelled"
    assert not any((ws / d).exists() for d in ("q1", "q2", "q3", "fourth"))
    # a search above the server's bound: 400, its limit beside the field at fault
    _fill_place(page, {**BOX, "x_step_mm": "0.05", "y_step_mm": "0.05", "out": "huge"})
    page.click("#pl-run")
    page.wait_for_selector("#view-use[data-place='error']", timeout=30_000)
    beside = page.inner_text(".use-msg[data-for='x_mm']")
    assert "above this server's limit of 1e+08 evaluations per request" in beside
    assert "--x-mm" not in beside and "\u201cx range (mm)\u201d" in beside
    assert not (ws / "huge").exists()
