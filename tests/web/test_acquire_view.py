"""The Acquire view's API (``/api/acquire``): a dry run, a detached acquisition on the
simulated lab, its state and event stream read from files, abort by the Ctrl-C path,
resume, refusals; and one browser test (start, live progress, reload and reattach,
abort)."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pytest

from tests.web.pages import acquire_dry_run, wait_text

pytestmark = pytest.mark.timeout(120)
#: the simulated lab's clock runs this much faster than the wall clock
FAST = 200.0
#: ... in the runs that are aborted: slow enough that the abort lands before the last test
#: ends (at 5 and 10 a run of 3 tests took 9-18 s on a loaded machine, and the abort came
#: after it: 'complete')
SLOW = 2.0


PROTOCOL = Path(__file__).parents[2] / "protocols" / "kr240-2.toml"


@pytest.fixture(scope="module")
def plan_dir(tmp_path_factory) -> Path:
    """A KR240-2 plan cut to 3 tests of 1 repeat."""
    import pandas as pd

    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    out = tmp_path_factory.mktemp("acq-plan") / "plan"
    write_plan(make_plan(load_protocol(PROTOCOL), candidates=500), out, figure=False)
    df = pd.read_csv(out / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df.iloc[:3].assign(repeats=1).to_csv(out / "plan.csv", index=False)
    return out


@pytest.fixture
def workspace(tmp_path, plan_dir) -> Path:
    """A workspace holding that plan (the conftest's app and client serve it)."""
    ws = tmp_path / "ws"
    ws.mkdir()
    shutil.copytree(plan_dir, ws / "plan")
    return ws


def _wait(client, run: str, until, timeout: float = 60.0) -> dict:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        s = client.get("/api/acquire/state", params={"run": run}).json()
        if until(s):
            return s
        time.sleep(0.05)
    raise AssertionError(f"timed out: {s}")


def _load_applied(s: dict) -> bool:
    return s["stage"] in ("load", "settle", "measure")


def _events(workspace: Path, run: str) -> list[str]:
    return [json.loads(line)["event"] for line in
            (workspace / run / "events.jsonl").read_text().splitlines()]


def test_dry_run_lists_the_motions_of_the_cli(client, workspace):
    from campaign.jobs.acquire import AcquireJobOptions, run

    r = client.post("/api/acquire/dry-run", json={"plan": "plan"})
    assert r.status_code == 200, r.text
    said: list[str] = []
    run(AcquireJobOptions(plan=workspace / "plan", dry_run=True),
        say=lambda s: said.extend(str(s).splitlines()))
    assert r.json()["motions"] == said and len(said) >= 3
    assert sorted(p.name for p in workspace.iterdir()) == ["plan"]


def test_paths_outside_the_workspace_and_hardware_refused(client, workspace, tmp_path):
    for body in ({"plan": "../plan", "out": "r"}, {"plan": "/etc", "out": "r"},
                 {"plan": "plan", "out": "../escape"}):
        r = client.post("/api/acquire/start", json=body)
        assert r.status_code == 400 and "workspace" in r.json()["detail"], r.text
    (workspace / "link").symlink_to(tmp_path)
    r = client.post("/api/acquire/start", json={"plan": "plan", "out": "link/run"})
    assert r.status_code == 400 and "leads out" in r.json()["detail"]
    r = client.post("/api/acquire/dry-run", json={"plan": "../x"})
    assert r.status_code == 400
    # a real robot from a server started without --hardware: refused, confirmed or not
    for confirm in (False, True):
        r = client.post("/api/acquire/start", json={"plan": "plan", "out": "hw", "fake": False,
                                                    "confirm": confirm})
        assert r.status_code == 403 and r.json()["detail"].startswith("hardware"), r.text
        r = client.post("/api/acquire/resume", json={"run": "plan", "fake": False,
                                                     "confirm": confirm})
        assert r.status_code == 403 and "--hardware" in r.json()["detail"], r.text
    # with --hardware, still not without the explicit confirmation
    from fastapi.testclient import TestClient

    from campaign.web.app import create_app
    from tests.web.conftest import TOKEN

    hw = TestClient(create_app(workspace, TOKEN, hardware=True))
    hw.get(f"/?token={TOKEN}")
    assert hw.get("/api/session").json()["hardware"] is True
    assert client.get("/api/session").json()["hardware"] is False
    r = hw.post("/api/acquire/start", json={"plan": "plan", "out": "hw", "fake": False},
                headers=client.headers)
    assert r.status_code == 400 and r.json()["detail"].startswith("confirmation"), r.text
    assert not (workspace / "hw").exists() and not (tmp_path / "run").exists()
    r = client.post("/api/acquire/start", json={"plan": "missing", "out": "r2"})
    assert r.status_code == 400 and not (workspace / "r2").exists()


def test_start_state_stream_abort_resume(client, workspace):
    r = client.post("/api/acquire/start", json={"plan": "plan", "out": "run",
                                                "time_scale": SLOW})
    assert r.status_code == 200, r.text
    pid = r.json()["pid"]
    s = _wait(client, "run", _load_applied)
    assert s["running"] and s["pid"] == pid and s["total"] == 3
    import os

    assert os.getsid(pid) == pid != os.getsid(0)  # its own session: the server's end is not its
    assert len(s["live"]["wrench_planned"] or s["live"]["wrench"]) == 6
    # a second start into the run being written, and a resume of it: refused
    again = client.post("/api/acquire/start", json={"plan": "plan", "out": "run"})
    assert again.status_code == 409, again.text
    again = client.post("/api/acquire/resume", json={"run": "run"})
    assert again.status_code == 409 and "lock" in again.json()["detail"]
    # a fresh app on the same workspace (a restarted server) sees the same run
    from fastapi.testclient import TestClient

    from campaign.web.app import create_app
    from tests.web.conftest import TOKEN

    other = TestClient(create_app(workspace, TOKEN))
    other.get(f"/?token={TOKEN}")
    assert other.get("/api/acquire/state").json()["pid"] == pid
    r = client.post("/api/acquire/abort", json={"run": "run"})
    assert r.status_code == 200 and r.json()["pid"] == pid
    # ended and its last line read (a poll between the two, once in CI, saw no finish yet)
    s = _wait(client, "run", lambda s: not s["running"] and s["finish"] is not None)
    # the page's words: the Abort button, not the terminal's Ctrl-C
    assert s["status"] == "aborted" and "(Abort)" in s["reason"] and "Ctrl-C" not in s["reason"]
    assert s["finish"]["status"] == "aborted"
    kinds = _events(workspace, "run")
    after = kinds[kinds.index("interrupt"):]
    assert "load_removed" in after and "robot_stopped" in after
    # the event stream replays the events file line for line, then ends
    with client.stream("GET", "/api/acquire/events", params={"run": "run"}) as sse:
        assert sse.headers["content-type"].startswith("text/event-stream")
        text = "".join(sse.iter_text())
    data = [json.loads(line[6:]) for line in text.splitlines() if line.startswith("data: {")]
    record = json.loads((workspace / ".gui" / "acquire" / "run.json").read_text())
    lines = (workspace / record["events_file"]).read_text().splitlines()
    assert [json.dumps(d) for d in data[:len(lines)]] == lines or data[:len(lines)] == [
        json.loads(x) for x in lines]
    assert data[0]["event"] == "start" and data[len(lines) - 1]["event"] == "finish"
    assert text.rstrip().endswith("data: {}")
    done_before = len(s["tests"])
    r = client.post("/api/acquire/resume", json={"run": "run", "time_scale": FAST})
    assert r.status_code == 200, r.text
    s = _wait(client, "run", lambda s: not s["running"] and s["status"] != "aborted")
    assert s["status"] == "complete", s
    assert [(t["test_id"], t["status"]) for t in s["tests"]] == [
        (1.0, "ok"), (2.0, "ok"), (3.0, "ok")] and done_before < 3
    import pandas as pd

    planned = pd.read_csv(workspace / "plan" / "plan.csv")
    for t, (_, p) in zip(s["tests"], planned.iterrows(), strict=True):
        assert 0 <= t["repeatability_mm"] < 0.5
        for f in ("fx_N", "fy_N", "fz_N"):  # the lab applies the planned force to 1 N
            assert abs(t[f] - p[f]) < 1.0, (f, t[f], p[f])


def test_browser_start_reload_reattach_abort_resume(server, workspace, open_url):
    page = open_url(server)
    assert acquire_dry_run(page, "plan", "gui-run", SLOW) >= 3
    page.click("#acq-start")
    wait_text(page, "#acq-stage", "load", "settle", "measure", timeout=30_000)
    assert page.locator("#acq-total").text_content() == "3"
    page.reload()
    page.click("#tab-acquire")
    page.wait_for_selector("#acq-plan", state="visible")
    wait_text(page, "#acq-running", "running", timeout=30_000)
    assert page.locator("#acq-run").text_content() == "gui-run"
    # abort once the reattached page shows a test under load (the case with a load to remove)
    wait_text(page, "#acq-stage", "load", "settle", "measure", timeout=30_000)
    page.click("#acq-abort")
    wait_text(page, "#acq-status", "aborted")
    state = json.loads((workspace / "gui-run" / "metadata.json").read_text())
    assert state["status"] == "aborted"
    kinds = _events(workspace, "gui-run")
    # the abort may land while a load is on (removed on the safe path) or between two
    # tests (nothing to remove): either way no load is left on the tool
    after = kinds[kinds.index("interrupt"):]
    assert "robot_stopped" in after and "load_left" not in kinds
    assert kinds.count("load_applied") == kinds.count("load_removed")
    if kinds[:kinds.index("interrupt")].count("load_applied") > \
            kinds[:kinds.index("interrupt")].count("load_removed"):
        assert "load_removed" in after
    rows = (workspace / "gui-run" / "tests.csv").read_text().splitlines()
    if len(rows) > 1:  # the table's first row: tests.csv's numbers (N, mm)
        head, first = rows[0].split(","), rows[1].split(",")
        cells = page.locator("#acq-tests tbody tr").first.locator("td").all_text_contents()
        row = dict(zip(head, first, strict=True))
        assert cells[3] == ", ".join(f"{float(row[c]):.1f}" for c in ("fx_N", "fy_N", "fz_N"))
        assert cells[5] == ", ".join(f"{float(row[c]):.3f}"
                                     for c in ("dx_mm", "dy_mm", "dz_mm"))
    shown = page.locator("#acq-done").text_content()
    assert int(shown) == len((workspace / "gui-run" / "tests.csv").read_text()
                             .splitlines()) - 1
    # resume the partial run from the page: it completes, every test measured once
    page.fill("#acq-scale", "50")
    page.click("#acq-resume")
    wait_text(page, "#acq-status", "complete")
    assert page.locator("#acq-done").text_content() == "3"
    assert page.locator("#acq-tests tbody tr").count() == 3
