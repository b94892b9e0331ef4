"""The Plan and Analyze views: their endpoints (TestClient) and the page (Chromium).

Numbers on the page are compared with the files the jobs wrote (plan.csv,
summary.json, results.json); a bad protocol value shows the command line's own
message beside its field.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path

import pandas as pd
import pytest

from tests.web.conftest import (
    TOKEN,  # noqa: F401  (the fixtures' token)
    browser_page,
    copy_acquired,
    gui_server,
    post_followed,
)
from tests.web.pages import wait_job


def _cli_message(tmp_path: Path, key_line: str, bad_line: str) -> str:
    """The message ``campaign plan`` prints for the shipped protocol with one line changed."""
    from analysis.errors import InputError
    from campaign.jobs.plan import PlanOptions, run

    text = (Path(__file__).parents[2] / "protocols" / "kr240-2.toml").read_text()
    assert key_line in text
    p = tmp_path / "cli" / "protocols" / "plan-gui.toml"
    p.parent.mkdir(parents=True)
    p.write_text(text.replace(key_line, bad_line))
    with pytest.raises(InputError) as err:
        run(PlanOptions(protocol=p, out=tmp_path / "cli" / "out", candidates=100))
    return str(err.value).split(": ", 2)[-1]  # without FILE:LINE


def test_plan_endpoint_writes_the_plan_and_protocol(client, workspace):
    r = post_followed(client, "/api/plan/run", json={"values": {"campaign.tests": "4",
                    "instruments.pose.noise.translation_um": "40",
                    "tool.xyz_mm": "0, 0, 120", "sampling.use_robot_zones": "true",
                    "safety.max_joint_speed_deg_s": "12"}, "candidates": 300,
                    "name": "p4"})
    assert r.status_code == 200, r.text
    d = r.json()
    plan = pd.read_csv(workspace / "plans" / "p4" / "plan.csv")
    summary = json.loads((workspace / "plans" / "p4" / "summary.json").read_text())
    assert len(plan) == len(d["rows"]) == summary["tests"] == 4
    assert d["summary"]["predicted_standard_errors"] == summary["predicted_standard_errors"]
    saved = (workspace / "protocols" / "p4.toml").read_text()
    assert "translation_um = 40" in saved and "tests = 4" in saved
    import tomllib

    doc = tomllib.loads(saved)
    assert doc["tool"]["xyz_mm"] == [0.0, 0.0, 120.0]
    assert doc["safety"]["max_joint_speed_deg_s"] == 12.0
    assert doc["sampling"]["use_robot_zones"] is True
    assert "plans/p4/plan_map.png" in d["files"]
    # the saved protocol is offered as a starting point
    assert "protocols/p4.toml" in client.get("/api/plan/protocols").json()["workspace"]
    form = client.get("/api/plan/form", params={"source": "protocols/p4.toml"}).json()
    assert form["values"]["campaign.tests"] == "4"


@pytest.mark.parametrize("key,line,bad", [
    ("campaign.tests", "tests = 5 ", "tests = -3 "),
    ("loads.selection", 'selection = "per-pose"', 'selection = "zz"'),
    ("thresholds.max_v_p", "max_v_p = 0.02 ", 'max_v_p = "x" ')])
def test_plan_endpoint_names_the_field_with_the_cli_message(client, tmp_path, key, line, bad):
    value = bad.split("=", 1)[1].strip().strip('"')
    r = post_followed(client, "/api/plan/run", json={"values": {key: value}, "candidates": 100})
    assert r.status_code == 400
    d = r.json()
    assert d["field"] == key
    assert d["detail"].split(": ", 2)[-1] == _cli_message(tmp_path, line, bad)


def test_plan_endpoint_refuses_bad_requests(client):
    assert post_followed(client, "/api/plan/run", json={"name": "../x"}).json()["field"] == "name"
    run = "/api/plan/run"
    assert post_followed(client, run, json={"values": {"nope.key": "1"}}).status_code == 400
    assert post_followed(client, run, json={"source": "/etc/passwd"}).status_code in (400, 422)
    r = post_followed(client, "/api/plan/run", json={"strategy": "best", "candidates": 100})
    assert r.status_code == 400 and r.json()["field"] == "strategy"


@pytest.fixture(scope="module")
def demo_ws(tmp_path_factory, acquired_kr240) -> Path:
    """A workspace holding a run of 6 tests (1 repeat) of the KR240-2 on the simulated
    lab (a copy of the session's :func:`~tests.web.conftest.acquired_kr240`: one
    acquisition for every module that analyses such a run)."""
    return copy_acquired(acquired_kr240, tmp_path_factory.mktemp("analyze-ws"))


def _client(ws: Path):
    from fastapi.testclient import TestClient

    from campaign.web.app import create_app
    from campaign.web.security import CSRF_HEADER, csrf_value

    c = TestClient(create_app(ws, "tok-0123456789abcdef"))
    c.get("/?token=tok-0123456789abcdef")
    c.headers[CSRF_HEADER] = csrf_value("tok-0123456789abcdef")
    return c


def _followed(ws: Path):
    """The app's client whose POST of a queued job answers with the job's end (200 and the
    result, or the error's status and record); the jobs in the queue's threads."""
    from tests.jobs.conftest import FollowedClient

    c = _client(ws)
    c.app.state.jobs_in_threads = True
    return FollowedClient(c)


def test_the_gui_analyzes_through_the_queued_job_only(demo_ws):
    """The Analyze view's path is the queued analyze job of /api/jobs: the page's fields,
    and the answer it reads (results.json's keys, analysis.json's, the verdict)."""
    c = _followed(demo_ws)
    assert c.post("/api/analyze/run", json={"run_dir": "run"}).status_code == 404
    r = c.post("/api/jobs/analyze", json={"run_dir": "run", "method": "ols", "report": False})
    assert r.status_code == 200, r.text
    r = c.post("/api/jobs/analyze", json={"run_dir": "run", "method": "wls"})
    assert r.status_code == 400 and "--force" in r.json()["detail"]  # analysed already
    assert r.json()["options"]["--force"] == "force"
    r = c.post("/api/jobs/analyze", json={"run_dir": "run", "method": "wls", "force": True,
                                          "report": False})
    assert r.status_code == 200, r.text
    d = r.json()
    res = json.loads((demo_ws / "run" / "analysis" / "results.json").read_text())
    assert res["method"] == d["method"] == "wls"
    for key in ("joints_identified", "joint_stiffness_Nm_per_rad", "ci95_Nm_per_rad",
                "standard_error_Nm_per_rad"):
        assert d[key] == res[key], key
    assert d["verdict"]["kind"] in ("verdict", "warning") and "p " in d["verdict"]["text"]
    assert d["files"]["results"] == "run/analysis/results.json"
    assert (d["status"], d["partial"], d["failed_rows"]) == ("complete", False, 0)
    assert c.post("/api/jobs/analyze", json={"run_dir": "../x"}).status_code == 400
    assert c.post("/api/jobs/analyze", json={"run_dir": "run", "method": "x"}).status_code == 422


# ---- the page ----

@pytest.fixture
def open_page(browser):
    """A function (workspace) -> a Chromium page on a GUI server of that workspace."""
    with contextlib.ExitStack() as stack:
        def make(ws: Path):
            page = stack.enter_context(browser_page(browser, stack.enter_context(
                gui_server(ws))))
            page.wait_for_function("() => document.body.dataset.planview === 'ready'",
                                   timeout=30_000)
            page.click("#tab-plan")
            return page

        yield make


def test_page_plans_and_shows_the_jobs_numbers(open_page, workspace):
    page = open_page(workspace)
    page.fill("#pf-campaign-tests", "6")
    page.fill("#plan-candidates", "400")
    page.fill("#pf-instruments-pose-noise-translation_um", "45")
    page.select_option("#plan-strategy", "d-optimal")
    page.click("#plan-run")
    wait_job(page, "plan", "done")
    out = workspace / "plans" / "plan-gui"
    plan = pd.read_csv(out / "plan.csv")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["strategy"] == "d-optimal" and summary["tests"] == 6
    rows = page.locator("#plan-rows tbody tr")
    assert rows.count() == len(plan) == 6
    for i, r in plan.iterrows():
        cells = rows.nth(i).locator("td")
        assert int(cells.nth(0).inner_text()) == r["test"]
        q = [float(v) for v in cells.nth(4).inner_text().split(",")]
        assert q == pytest.approx([r[f"q{j}_model_deg"] for j in range(1, 7)], abs=6e-4)
    for j in summary["predicted_standard_errors"]:
        row = page.locator(f"#plan-se-k{j['joint']}")
        assert float(row.locator("td.se").inner_text()) == pytest.approx(
            j["se_design_N_m_per_rad"] / 1e3, abs=6e-4)
        assert float(row.locator("td.se-pct").inner_text()) == pytest.approx(
            j["se_design_percent"], abs=6e-4)
    assert "translation_um = 45" in (workspace / "protocols" / "plan-gui.toml").read_text()
    # the zone map the job drew is shown
    page.wait_for_function("() => pv.plots['plan-map-fig'] !== undefined")


def test_page_shows_the_cli_message_beside_the_field(open_page, workspace, tmp_path):
    page = open_page(workspace)
    page.fill("#pf-campaign-tests", "-3")
    page.click("#plan-run")
    wait_job(page, "plan", "error")
    shown = page.locator("[data-key='campaign.tests'] .pv-msg").inner_text()
    assert shown.split(": ", 2)[-1] == _cli_message(tmp_path, "tests = 5 ", "tests = -3 ")
    assert page.locator("#plan-error").inner_text() == ""
    assert page.locator("[data-key='campaign.repeats'] .pv-msg").inner_text() == ""


def test_page_analyzes_a_run_and_shows_results_json(open_page, demo_ws):
    page = open_page(demo_ws)
    page.select_option("#an-run", "run")
    page.select_option("#an-method", "wls")
    page.select_option("#an-robust", "huber")
    page.check("#an-force")
    page.click("#an-run-btn")
    page.wait_for_function("() => !['running', 'error'].includes(document.body.dataset.analyze)"
                           " || document.getElementById('an-error').textContent === ''"
                           " && document.body.dataset.analyze === 'error'", timeout=90_000)
    reasons = []
    if page.evaluate("() => document.body.dataset.analyze") == "error":
        # refused (this small run's huber fit down-weights too much): the reasons are
        # listed; accepting them writes the result, recorded as --accept-misfit does
        assert page.locator("#an-error").inner_text() == ""
        reasons = page.locator("#an-reasons li").all_inner_texts()
        assert reasons and page.locator("#an-refused").is_visible()
        page.click("#an-retry")
        page.wait_for_function("() => document.body.dataset.analyze === 'done'",
                               timeout=90_000)
        assert "ACCEPTED DESPITE A REFUSAL" in page.locator("#an-verdict").inner_text()
    res = json.loads((demo_ws / "run" / "analysis" / "results.json").read_text())
    assert res["method"] == "wls" and res["robust"] is not None
    assert res["misfit_accepted"]["accepted"] == bool(reasons)
    assert res["misfit_accepted"]["problems"] == reasons
    for j, k, (lo, hi) in zip(res["joints_identified"], res["joint_stiffness_Nm_per_rad"],
                              res["ci95_Nm_per_rad"], strict=True):
        row = page.locator(f"#an-k{j}")
        assert float(row.locator("td.k").inner_text()) == pytest.approx(k / 1e3, abs=0.051)
        assert float(row.locator("td.lo").inner_text()) == pytest.approx(lo / 1e3, abs=0.051)
        assert float(row.locator("td.hi").inner_text()) == pytest.approx(hi / 1e3, abs=0.051)
    assert "p " in page.locator("#an-verdict").inner_text()
    assert page.locator("#an-status").inner_text().startswith("run run: complete")
    link = page.locator("#an-links a", has_text="report.html")
    r = page.request.get(link.evaluate("a => a.href"))
    assert r.status == 200 and "<html" in r.text().lower()
