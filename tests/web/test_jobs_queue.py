"""The queue of long jobs over HTTP: 202 and the job's state, its server-sent events, a
cancellation that leaves no files, 429 when full, the per-request bounds (400 naming the
limit), and refusals that name the request field besides the command line's options."""

from __future__ import annotations

import json
import shutil
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[2]
#: a search of 441 placements (about 2 s in one process)
PLACE = {"robot": "kr240-2", "path": "part.csv", "x_mm": "1400..1800", "y_mm": "-200..200",
         "z_mm": "200", "x_step_mm": 20, "y_step_mm": 20, "tool_angle_step_deg": 30,
         "config": "-1,-1,-1", "workers": 0}
#: the same box with 5 mm steps: 6561 placements, tens of seconds (cancelled in the tests)
LONG = {**PLACE, "x_step_mm": 5, "y_step_mm": 5}


@pytest.fixture
def ws(workspace) -> Path:
    shutil.copy(ROOT / "examples" / "part_circle.csv", workspace / "part.csv")
    shutil.copy(ROOT / "examples" / "kr240-2_path.csv", workspace / "path.csv")
    return workspace


@pytest.fixture
def in_threads(app):
    """The app's jobs in the queue's threads: for the tests of what the queue answers, not
    of the job processes (each would add its start-up, seconds on a loaded machine)."""
    app.state.jobs_in_threads = True


def _wait(client, job_id: str, until=("done", "failed", "cancelled"), timeout=120.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] in until:
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id}: still {job['state']}")


def _running(client, job_id: str) -> dict:
    """Wait until the job has reported progress of its search (fraction > 0)."""
    end = time.monotonic() + 60
    while time.monotonic() < end:
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] == "running" and (job["fraction"] or 0) > 0:
            return job
        assert job["state"] in ("queued", "running"), job
        time.sleep(0.02)
    raise AssertionError("the job never reported progress")


def test_place_job_queued_with_progress_events(client, ws):
    from campaign.jobs.place import PlaceOptions, run

    answer = client.post("/api/jobs/place", json={**PLACE, "out": "p"})
    assert answer.status_code == 202, answer.text
    job = answer.json()
    assert job["state"] in ("queued", "running") and answer.headers["location"] == \
        f"/api/jobs/{job['id']}"
    lines = []
    with client.stream("GET", f"/api/jobs/{job['id']}/events") as events:
        for line in events.iter_lines():
            lines.append(line)
    states = [json.loads(x[6:]) for x in lines if x.startswith("data: {\"")]
    assert "event: end" in lines
    assert states[-1]["state"] == "done"
    fractions = [s["fraction"] for s in states if s["fraction"] is not None]
    assert fractions == sorted(fractions) and fractions[-1] == 1.0
    assert any(0 < f < 1 for f in fractions)  # the search's own progress, task by task
    assert any("searching:" in s["text"] for s in states)
    done = client.get(f"/api/jobs/{job['id']}").json()
    on_disk = json.loads((ws / "p" / "placement.json").read_text())
    # the answer names workspace files relative to it (the file, by absolute path)
    assert done["result"] == json.loads(json.dumps(on_disk).replace(f"{ws}/", ""))
    # the job itself, run here into another directory, finds the same placement
    mine = run(PlaceOptions(**{**PLACE, "path": ws / "part.csv", "out": ws / "mine"}))
    assert mine.placement["placement"] == done["result"]["placement"]
    assert mine.placement["objective"] == done["result"]["objective"]


def test_cancel_stops_the_search_and_leaves_no_files(client, ws):
    job = client.post("/api/jobs/place", json={**LONG, "out": "deep/long"}).json()
    _running(client, job["id"])
    t0 = time.monotonic()
    assert client.delete(f"/api/jobs/{job['id']}").status_code == 200
    end = _wait(client, job["id"])
    assert end["state"] == "cancelled" and end["result"] is None
    assert time.monotonic() - t0 < 10  # stopped at its next task, not at the end
    assert not (ws / "deep").exists()
    # cancelling again, or a finished job: it stays as it ended
    again = client.post(f"/api/jobs/{job['id']}/cancel")
    assert again.status_code == 200 and again.json()["state"] == "cancelled"
    assert client.get("/api/jobs/nope").status_code == 404
    assert client.delete("/api/jobs/nope").status_code == 404


def test_a_full_queue_answers_429(client, app, ws, in_threads):
    from campaign.web.job_queue import JobQueue
    from campaign.web.job_submit import _record

    app.state.jobs = JobQueue(workers=1, waiting=1, describe_error=_record)
    first = client.post("/api/jobs/place", json={**LONG, "out": "a"})
    second = client.post("/api/jobs/place", json={**LONG, "out": "b"})
    assert first.status_code == 202 and second.status_code == 202
    third = client.post("/api/jobs/place", json={**LONG, "out": "c"})
    assert third.status_code == 429, third.text
    assert third.json()["detail"].startswith("the job queue is full (")
    assert "1 at a time and queues 1" in third.json()["detail"]
    queued = client.delete(f"/api/jobs/{second.json()['id']}").json()
    assert queued["state"] == "cancelled"  # a waiting job ends at once
    client.delete(f"/api/jobs/{first.json()['id']}")
    assert _wait(client, first.json()["id"])["state"] == "cancelled"
    assert not any((ws / d).exists() for d in "abc")
    fourth = client.post("/api/jobs/place", json={**PLACE, "out": "d"})
    assert fourth.status_code == 202
    # waited for: left running in the queue's thread it drew its figures beside the next
    # tests' own (matplotlib's text parser is not thread-safe: a CI failed on it)
    assert _wait(client, fourth.json()["id"])["state"] == "done"


@pytest.mark.parametrize(("job", "body", "field", "limit"), [
    ("robustness", {"robot": "kr240-2", "trials": 10000, "tests": list(range(1, 21))},
     "trials", "limit of 100000 per request"),
    ("plan", {"protocol": "plan/protocol.toml", "out": "x", "candidates": 200000},
     "candidates", "limit of 100000 per request"),
    ("place", {**PLACE, "out": "x", "x_step_mm": 0.05, "y_step_mm": 0.05},
     "x_mm", "limit of 1e+08 evaluations per request"),
    ("maps", {"robot": "kr240-2", "out": "x", "step_rad": 1e-4}, "step_rad",
     "limit of 4e+06 per request"),
])
def test_bounds_are_refused_naming_the_limit(client, ws, job, body, field, limit):
    answer = client.post(f"/api/jobs/{job}", json=body)
    assert answer.status_code == 400, answer.text
    doc = answer.json()
    assert limit in doc["detail"] and doc["field"] == field
    assert not (ws / "x").exists()


def test_refusal_names_the_field_and_the_options_it_mentions(client, ws, in_threads):
    (ws / "c").mkdir()
    (ws / "c" / "old.txt").write_text("earlier output")
    body = {"robot": "kr240-2", "path": "path.csv", "out": "c",
            "wrench_N_Nm": [500, 0, -1000, 0, 20, 0]}
    job = client.post("/api/jobs/compensate", json=body).json()
    end = _wait(client, job["id"])
    assert end["state"] == "failed"
    err = end["error"]
    assert err["status"] == 400 and "add --force" in err["detail"]
    assert err["field"] == "out" and err["options"] == {"--force": "force", "--out": "out"}
    assert (ws / "c" / "old.txt").read_text() == "earlier output"
    # a synchronous job: the same record in the 400 answer
    bad = client.post("/api/jobs/stiffness", json={"robot": "kr240-2", "q_rad": [0] * 6,
                                                   "wrench_N_Nm": [1, 2]})
    assert bad.status_code == 400
    assert bad.json()["field"] == "wrench_N_Nm"
    assert bad.json()["options"] == {"--wrench": "wrench_N_Nm"}


def test_path_deflection_from_the_workspace_or_uploaded(client, ws):
    """The deflection and its band equal the compensation's prediction (compensated.csv)."""
    import numpy as np
    import pandas as pd

    from campaign.jobs.compensate import CompensateOptions
    from campaign.jobs.compensate import run as compensate

    wrench = [500, 0, -1000, 0, 20, 0]
    text = (ws / "path.csv").read_text()
    a = client.post("/api/use/deflection", json={"robot": "kr240-2", "path": "path.csv",
                                                 "wrench_N_Nm": wrench})
    b = client.post("/api/use/deflection", json={"robot": "kr240-2", "upload_name": "mine.csv",
                                                 "upload_text": text, "wrench_N_Nm": wrench})
    assert a.status_code == 200 and b.status_code == 200, (a.text, b.text)
    assert a.json() == b.json()
    compensate(CompensateOptions(robot="kr240-2", path=ws / "path.csv", out=ws / "comp",
                                 wrench_N_Nm=wrench))
    table = pd.read_csv(ws / "comp" / "compensated.csv")
    got = np.asarray(a.json()["deflection_m_rad"])
    assert np.allclose(1e3 * got[:, 0], table["dx_mm"], rtol=1e-10, atol=1e-12)
    assert np.allclose(1e3 * got[:, 2], table["dz_mm"], rtol=1e-10, atol=1e-12)
    assert a.json()["lo95_m_rad"] is None  # nominal k: no band
    # a bad line of an upload: the reader's file:line message, with the uploaded name
    lines = text.splitlines()
    cells = lines[3].split(",")
    head = lines[0].split(",")
    cells[head.index("q2_deg")] = "abc"
    lines[3] = ",".join(cells)
    bad = client.post("/api/use/deflection", json={"robot": "kr240-2", "upload_name": "mine.csv",
                                                   "upload_text": "\n".join(lines),
                                                   "wrench_N_Nm": wrench})
    assert bad.status_code == 400
    assert bad.json()["detail"] == "mine.csv:4 (point 3): column q2_deg: 'abc' is not a finite " \
                                   "number"
    assert bad.json()["field"] == "path"
    assert list((ws / ".gui" / "uploads").iterdir()) == []  # the upload is gone once read
    big = client.post("/api/use/deflection", json={"robot": "kr240-2", "upload_name": "a.csv",
                                                   "upload_text": "x" * 2_000_001})
    assert big.status_code == 422 and "2000000" in big.json()["detail"]
    for name in ("../a.csv", "a.txt", ".csv"):
        r = client.post("/api/use/deflection", json={"robot": "kr240-2", "upload_name": name,
                                                     "upload_text": text})
        assert r.status_code == 400 and r.json()["field"] == "upload_name", name


@pytest.mark.parametrize(("job", "body", "said"), [
    ("robustness", {"robot": "kr240-2", "tests": [4, 8], "trials": 30, "pool_size": 60,
                    "method": "ols"}, "of 60 simulated campaigns identified"),
    ("maps", {"robot": "kr240-2", "out": "m", "step_rad": 0.5}, "plots"),  # its last stage
])
def test_jobs_report_their_own_progress(client, ws, in_threads, job, body, said):
    queued = client.post(f"/api/jobs/{job}", json=body)
    assert queued.status_code == 202, queued.text
    with client.stream("GET", f"/api/jobs/{queued.json()['id']}/events") as events:
        states = [json.loads(x[6:]) for x in events.iter_lines()
                  if x.startswith('data: {"')]
    assert states[-1]["state"] == "done", states[-1]
    assert any(said in s["text"] for s in states), [s["text"] for s in states]
    if job == "robustness":  # fractions of the 60 campaigns, in order, to the end
        fractions = [s["fraction"] for s in states if s["fraction"] is not None]
        assert fractions == sorted(fractions) and fractions[-1] == 1.0
        assert len(states[-1]["result"]["results"]) == 2 * 6


def test_cancelled_acquisition_takes_the_ctrl_c_path_and_keeps_its_run(client, ws):
    import pandas as pd

    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    write_plan(make_plan(load_protocol(ROOT / "protocols" / "kr240-2.toml"), candidates=500),
               ws / "real", figure=False)
    df = pd.read_csv(ws / "real" / "plan.csv", dtype={"zone": str, "load_case": str,
                                                      "method": str})
    df.iloc[:3].assign(repeats=1).to_csv(ws / "real" / "plan.csv", index=False)
    queued = client.post("/api/jobs/acquire", json={"plan": "real", "out": "runs/r1",
                                                    "fake": True, "assume_yes": True,
                                                    "time_scale": 20.0})
    assert queued.status_code == 202, queued.text
    job_id = queued.json()["id"]
    end = time.monotonic() + 60
    while time.monotonic() < end:  # the first test under way
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] == "running" and job["text"].startswith("test "):
            break
        assert job["state"] in ("queued", "running"), job
        time.sleep(0.05)
    client.delete(f"/api/jobs/{job_id}")
    job = _wait(client, job_id)
    assert job["state"] == "cancelled" and "acquisition was stopped" in job["text"], job
    assert "Ctrl-C" not in job["text"] and "(Abort)" in job["text"], job
    meta = json.loads((ws / "runs" / "r1" / "metadata.json").read_text())
    assert meta["status"] == "aborted"  # recorded, resumable, as the command line's Ctrl-C


EXITING = """
import sys, time
from pathlib import Path
from fastapi import FastAPI
from fastapi.testclient import TestClient
from campaign.web.api_jobs import router

if __name__ == "__main__":
    app = FastAPI()
    app.state.workspace = Path(sys.argv[1])
    app.include_router(router)
    c = TestClient(app)
    job = c.post("/api/jobs/place", json={**__BODY__, "out": "long"}).json()
    while (c.get("/api/jobs/" + job["id"]).json()["fraction"] or 0) == 0:
        time.sleep(0.05)
    print("searching", flush=True)
"""


def test_a_server_that_exits_interrupts_its_jobs_and_leaves_no_files(ws, tmp_path):
    """The job's process is not waited for: it takes its Ctrl-C path, OUT is removed."""
    import os
    import subprocess
    import sys

    script = tmp_path / "exiting.py"
    script.write_text(EXITING.replace("__BODY__", repr(LONG)))
    proc = subprocess.Popen([sys.executable, str(script), str(ws)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=os.environ.copy())
    try:
        # timed from the server's exit (the script's last line), not from its start: the
        # start-up of the two interpreters is not what is tested, and takes tens of
        # seconds on a loaded machine
        said = proc.stdout.readline()
        t0 = time.monotonic()
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0 and "searching" in said, err
    assert time.monotonic() - t0 < 25  # not the whole search (about 30 s on one core)
    assert not (ws / "long").exists()
