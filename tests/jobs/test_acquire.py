"""acquire: the CLI and the web API measure the same tests.csv on the seeded simulated lab;
the job runs in its own process, reports through an events file and aborts as Ctrl-C does."""

from __future__ import annotations

import json
import pickle
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from analysis.errors import InputError
from campaign.jobs.acquire import AcquireJobOptions, abort, run
from tests.jobs.conftest import cli, cli_error

pytestmark = pytest.mark.timeout(240)
PROTOCOL = Path(__file__).parents[2] / "protocols" / "kr240-2.toml"
#: simulated time runs this much faster than the wall clock
SCALE = 200.0


@pytest.fixture(scope="session")
def plan_dir(tmp_path_factory) -> Path:
    """A KR240-2 plan cut to 2 tests of 1 repeat."""
    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    out = tmp_path_factory.mktemp("jobs-plan") / "plan"
    write_plan(make_plan(load_protocol(PROTOCOL), candidates=500), out, figure=False)
    df = pd.read_csv(out / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df = df.iloc[:2].assign(repeats=1)
    df.to_csv(out / "plan.csv", index=False)
    return out


@pytest.fixture
def plan(ws, plan_dir) -> str:
    shutil.copytree(plan_dir, ws / "plan")
    return "plan"


def _measured(path: Path) -> list[str]:
    """tests.csv without its wall-clock time stamps (the last column)."""
    return [line.rsplit(",", 1)[0] for line in path.read_text().splitlines()]


def test_acquire_same_tests_csv_from_cli_and_api(ws, client, plan):
    proc = cli(ws, "acquire", "--plan", plan, "--out", "cli", "--fake", "--yes", "--quiet",
               "--time-scale", str(SCALE))
    assert proc.returncode == 0, proc.stderr
    answer = client.post("/api/jobs/acquire", json={
        "plan": plan, "out": "api", "fake": True, "assume_yes": True, "time_scale": SCALE})
    assert answer.status_code == 200, answer.text
    got = answer.json()
    assert got["status"] == "complete" and got["run_dir"] == "api"
    assert got["ok"] == 2 and got["failed"] == 0 and got["exported"]
    rows = _measured(ws / "api" / "tests.csv")
    assert rows == _measured(ws / "cli" / "tests.csv")
    assert len(rows) == 1 + 2
    meta = json.loads((ws / "api" / "metadata.json").read_text())
    assert meta["status"] == "complete"


def test_acquire_refusals_same_line(ws, client, plan):
    for body, args in (
        ({"plan": plan, "time_scale": 10.0}, ["--plan", plan, "--time-scale", "10"]),
        ({"plan": plan, "fake": True, "time_scale": -1.0},
         ["--plan", plan, "--fake", "--time-scale", "-1"]),
        ({}, []),
        ({"plan": plan, "out": "x", "resume": "y"}, ["--plan", plan, "--out", "x",
                                                      "--resume", "y"]),
    ):
        answer = client.post("/api/jobs/acquire", json=body)
        assert answer.status_code == 400, answer.text
        assert answer.json()["detail"] == cli_error(ws, "acquire", *args)
    # no confirmation possible through the API: a run without assume_yes is refused
    answer = client.post("/api/jobs/acquire", json={"plan": plan, "out": "n", "fake": True})
    assert answer.status_code == 400 and answer.json()["detail"].startswith("confirmation")
    assert not (ws / "n").exists()


def test_dry_run_moves_nothing(ws, client, plan):
    answer = client.post("/api/jobs/acquire", json={"plan": plan, "dry_run": True})
    assert answer.status_code == 200
    assert answer.json()["status"] == "dry-run" and answer.json()["run_dir"] is None
    assert sorted(p.name for p in ws.iterdir()) == ["plan"]


def test_options_record_round_trips_through_json(tmp_path):
    o = AcquireJobOptions(plan=Path("p"), out=tmp_path / "r", fake=True, time_scale=50.0,
                          events_file=Path("e.jsonl"))
    assert AcquireJobOptions.from_dict(json.loads(json.dumps(o.to_dict()))) == o
    assert pickle.loads(pickle.dumps(o)) == o  # for a multiprocessing start, too
    with pytest.raises(InputError, match="unknown option"):
        AcquireJobOptions.from_dict({"plan": "p", "yes": True})


def _load_hangs(events: Path) -> bool:
    text = events.read_text() if events.exists() else ""
    return text.count('"load_applied"') > text.count('"load_removed"')


def test_job_in_its_own_process_aborts_by_signal_like_ctrl_c(ws, plan):
    """Run in a process of its own, the job reports to an events file and SIGINT takes the
    Ctrl-C path: load removed, robot stopped, 'aborted' recorded; a resume completes it."""
    events = ws / "events.jsonl"
    options = AcquireJobOptions(plan=ws / plan, out=ws / "run", fake=True, assume_yes=True,
                                time_scale=20.0, events_file=events)
    (ws / "options.json").write_text(json.dumps(options.to_dict()))
    proc = subprocess.Popen([sys.executable, "-m", "campaign.jobs.acquire",
                             str(ws / "options.json")], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 90
    while time.monotonic() < deadline and not _load_hangs(ws / "run" / "events.jsonl"):
        assert proc.poll() is None, proc.stderr.read()
        time.sleep(0.005)
    abort(proc.pid)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 1, err
    result = json.loads(out.strip().splitlines()[-1])
    # the job's process has no terminal: its SIGINT is the page's Abort, named so
    assert result["status"] == "aborted" and "(Abort)" in result["reason"]
    assert "Ctrl-C" not in result["reason"]
    meta = json.loads((ws / "run" / "metadata.json").read_text())
    assert meta["status"] == "aborted" and meta["reason"] == "stopped by the operator (Abort)"
    kinds = [json.loads(line)["event"] for line in
             (ws / "run" / "events.jsonl").read_text().splitlines()]
    after = kinds[kinds.index("interrupt"):]
    assert "robot_stopped" in after and "load_removed" in after
    progress = [json.loads(line) for line in events.read_text().splitlines()]
    assert progress[0]["event"] == "start" and progress[-1]["event"] == "finish"
    assert progress[-1]["status"] == "aborted"
    assert any(p["event"] == "phase" for p in progress)
    done = run(AcquireJobOptions(resume=ws / "run", fake=True, assume_yes=True,
                                 time_scale=SCALE))
    assert done.status == "complete" and done.succeeded
    assert len(pd.read_csv(ws / "run" / "tests.csv")) == 2


def test_should_abort_takes_the_ctrl_c_path(ws, plan):
    phases = []

    def should_abort() -> bool:
        phases.append(1)
        return len(phases) > 12  # a few phases into the first test

    result = run(AcquireJobOptions(plan=ws / plan, out=ws / "run", fake=True,
                                   assume_yes=True, time_scale=SCALE),
                 should_abort=should_abort)
    assert result.status == "aborted" and result.reason == "stopped by the operator (Abort)"
    assert not result.succeeded
    meta = json.loads((ws / "run" / "metadata.json").read_text())
    assert meta["status"] == "aborted"
    kinds = [json.loads(line)["event"] for line in
             (ws / "run" / "events.jsonl").read_text().splitlines()]
    assert "robot_stopped" in kinds[kinds.index("interrupt"):]
