"""The API's safety rules through the page's own token and CSRF header (issue 29):

* no route starts or resumes an acquisition on a real robot from a server started
  without ``--hardware`` (every operation of the OpenAPI document that takes ``fake``
  is walked, and a listener at the plan's robot address must get no connection);
* one robot, one acquisition at a time, whichever route started the first;
* a client cannot name a file the server appends to (``events_file``), abort another
  run than the one it names (``kx__ky`` and ``kx/ky``), choose the Dask scheduler the
  server connects to, or make the plan form read a robot file outside the workspace;
* one path rule for every route (a symbolic link is refused, even one leading inside);
* the bounds the command line has (pool size, time scale) with its line, and 413 for
  a body over the server's limit.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.jobs.conftest import cli_error
from tests.web.conftest import TOKEN

pytestmark = pytest.mark.timeout(180)
ROOT = Path(__file__).parents[2]


@pytest.fixture(scope="module")
def plan_dir(tmp_path_factory) -> Path:
    """A KR240-2 plan cut to 3 tests of 1 repeat (acquirable on the simulated lab)."""
    import pandas as pd

    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    out = tmp_path_factory.mktemp("safety-plan") / "plan"
    write_plan(make_plan(load_protocol(ROOT / "protocols" / "kr240-2.toml"), candidates=500),
               out, figure=False)
    df = pd.read_csv(out / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df.iloc[:3].assign(repeats=1).to_csv(out / "plan.csv", index=False)
    return out


@pytest.fixture
def workspace(tmp_path, plan_dir) -> Path:
    """A workspace holding that plan and a robot file (the conftest's app and client
    serve it)."""
    from analysis.model.robots import builtin_files

    ws = tmp_path / "ws"
    ws.mkdir()
    shutil.copytree(plan_dir, ws / "plan")
    shutil.copy(builtin_files()["kr240-2"], ws / "robot.toml")
    return ws


@contextlib.contextmanager
def listener():
    """A TCP socket listening on 127.0.0.1 (a free port): (its port, a function that
    says whether anybody connected so far)."""
    sock = socket.socket()
    sock.bind(("127.0.0.1", 0))
    sock.listen(8)
    sock.setblocking(False)

    def connected() -> bool:
        try:
            conn, _ = sock.accept()
        except BlockingIOError:
            return False
        conn.close()
        return True

    try:
        yield sock.getsockname()[1], connected
    finally:
        sock.close()


def _robot_at(plan: Path, port: int) -> None:
    """The plan's protocol copy with its robot controller at 127.0.0.1:``port``."""
    proto = plan / "protocol.toml"
    text = proto.read_text()
    assert 'address = "socket://192.168.1.20:7000"' in text
    proto.write_text(text.replace("socket://192.168.1.20:7000", f"socket://127.0.0.1:{port}"))


def _client(app):
    from fastapi.testclient import TestClient

    from campaign.web.security import CSRF_HEADER, csrf_value

    c = TestClient(app)
    assert c.get(f"/?token={TOKEN}").status_code == 200
    c.headers[CSRF_HEADER] = csrf_value(TOKEN)
    return c


def _acquisition_routes(client) -> dict[str, dict]:
    """The POST operations whose body has a ``fake`` field (they reach the acquire job):
    path -> the body's properties."""
    doc = client.get("/openapi.json").json()
    comps = doc["components"]["schemas"]
    found = {}
    for path, ops in doc["paths"].items():
        body = ops.get("post", {}).get("requestBody", {}).get("content", {}).get(
            "application/json")
        if body is None:
            continue
        schema = body["schema"]
        if "$ref" in schema:
            schema = comps[schema["$ref"].rsplit("/", 1)[-1]]
        if "fake" in schema.get("properties", {}):
            found[path] = schema["properties"]
    return found


def test_no_route_drives_a_real_robot_without_hardware(client, workspace):
    routes = _acquisition_routes(client)
    assert {"/api/acquire/start", "/api/acquire/resume", "/api/jobs/acquire"} <= set(routes)
    values = {"plan": "plan", "out": "r", "run": "plan", "fake": False, "confirm": True,
              "assume_yes": True}
    with listener() as (port, connected):
        _robot_at(workspace / "plan", port)
        before = sorted(p.name for p in workspace.iterdir())
        for path, props in routes.items():
            body = {k: v for k, v in values.items() if k in props}
            r = client.post(path, json=body)
            assert r.status_code == 403, (path, r.text)
            assert "--hardware" in r.json()["detail"], r.text
        time.sleep(0.5)  # a job started anyway would be connecting by now
        assert not connected()
        assert sorted(p.name for p in workspace.iterdir()) == before


def test_with_hardware_every_route_still_needs_the_confirmation(workspace):
    from campaign.web.app import create_app

    hw = _client(create_app(workspace, TOKEN, hardware=True))
    routes = _acquisition_routes(hw)
    values = {"plan": "plan", "out": "r", "run": "plan", "fake": False}
    with listener() as (port, connected):
        _robot_at(workspace / "plan", port)
        for path, props in routes.items():
            r = hw.post(path, json={k: v for k, v in values.items() if k in props})
            assert r.status_code == 400, (path, r.text)
            assert r.json()["detail"].startswith("confirmation"), r.text
        assert not connected()


def test_a_dry_run_on_hardware_connects_nothing(client, workspace):
    with listener() as (port, connected):
        _robot_at(workspace / "plan", port)
        r = client.post("/api/jobs/acquire", json={"plan": "plan", "dry_run": True})
        assert r.status_code == 202, r.text
        from tests.jobs.conftest import wait_job

        job = wait_job(client, r.json()["id"])
        assert job["state"] == "done" and job["result"]["status"] == "dry-run", job
        assert not connected()


def _state(client, run: str, until, timeout: float = 120.0) -> dict:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        s = client.get("/api/acquire/state", params={"run": run}).json()
        if until(s):
            return s
        time.sleep(0.05)
    raise AssertionError(f"{run}: {s}")


def _stop_detached(workspace: Path) -> None:
    """SIGINT every acquisition the Acquire view started in ``workspace`` still running."""
    import json

    for record in (workspace / ".gui" / "acquire").glob("*.json"):
        pid = json.loads(record.read_text()).get("pid")
        with contextlib.suppress(OSError):
            if b"campaign.jobs.acquire" in Path(f"/proc/{pid}/cmdline").read_bytes():
                os.kill(pid, signal.SIGINT)


def _wait_for_the_acquiring_process_to_end(workspace, bound_s: float = 120.0):
    """The Acquire view's records name their process; its claim on the robot ends with it,
    which can be a moment after the record says the run finished."""
    pids = [json.loads(r.read_text()).get("pid")
            for r in (workspace / ".gui" / "acquire").glob("*.json")]
    end = time.monotonic() + bound_s
    for pid in filter(None, pids):
        while Path(f"/proc/{pid}").exists() and time.monotonic() < end:
            with contextlib.suppress(ChildProcessError, OSError):
                os.waitpid(pid, os.WNOHANG)  # reap it, where it is this process's child
            time.sleep(0.05)


def test_one_acquisition_per_robot_through_every_route(client, workspace):
    try:
        _one_per_robot(client, workspace)
    finally:
        _stop_detached(workspace)


def _one_per_robot(client, workspace):
    from tests.jobs.conftest import wait_job

    r = client.post("/api/acquire/start", json={"plan": "plan", "out": "r1",
                                                "time_scale": 1.0})
    assert r.status_code == 200, r.text
    _state(client, "r1", lambda s: s["running"] and s["live"].get("phase"))
    # the same robot (the plan's [instruments.robot]) from each route: 409, nothing made
    for path, body in (("/api/acquire/start", {"plan": "plan", "out": "r2"}),
                       ("/api/jobs/acquire", {"plan": "plan", "out": "r3", "fake": True,
                                              "assume_yes": True})):
        again = client.post(path, json=body)
        assert again.status_code == 409, (path, again.text)
        assert "one robot, one acquisition at a time" in again.json()["detail"]
    assert not (workspace / "r2").exists() and not (workspace / "r3").exists()
    # a dry run moves nothing: allowed
    assert client.post("/api/acquire/dry-run", json={"plan": "plan"}).status_code == 200
    assert client.post("/api/acquire/abort", json={"run": "r1"}).status_code == 200
    _state(client, "r1", lambda s: not s["running"] and s["finish"] is not None)
    _wait_for_the_acquiring_process_to_end(workspace)
    # the robot is free again once the first acquisition's process has ended: the queue's
    # job holds it in turn, and the Acquire view's start and resume are refused meanwhile
    queued = client.post("/api/jobs/acquire", json={"plan": "plan", "out": "r3",
                                                    "fake": True, "assume_yes": True,
                                                    "time_scale": 1.0})
    assert queued.status_code == 202, queued.text
    job_id = queued.json()["id"]
    end = time.monotonic() + 120
    while time.monotonic() < end:
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] == "running" and job["text"].startswith("test "):
            break
        assert job["state"] in ("queued", "running"), job
        time.sleep(0.05)
    for path, body in (("/api/acquire/start", {"plan": "plan", "out": "r4"}),
                       ("/api/acquire/resume", {"run": "r1"})):
        again = client.post(path, json=body)
        assert again.status_code == 409, (path, again.text)
        assert "one robot, one acquisition at a time" in again.json()["detail"]
    client.delete(f"/api/jobs/{job_id}")
    assert wait_job(client, job_id)["state"] == "cancelled"


def test_events_file_cannot_name_an_existing_file(client, workspace):
    target = workspace / "plan" / "plan.csv"
    before = target.read_bytes()
    r = client.post("/api/jobs/acquire", json={"plan": "plan", "out": "r", "fake": True,
                                               "assume_yes": True,
                                               "events_file": "plan/plan.csv"})
    assert r.status_code == 400, r.text
    assert r.json()["detail"].startswith("events_file: an existing file, refused")
    assert target.read_bytes() == before and not (workspace / "r").exists()


def test_abort_names_one_run_only(client, workspace):
    from campaign.web.acquire_api import _key, _record_path

    assert _key(workspace, workspace / "kx__ky") != _key(workspace, workspace / "kx" / "ky")
    assert len({_key(workspace, workspace / n) for n in ("a/b", "a__b", "a%2Fb", "a%b",
                                                           "x" * 300, "y" * 300)}) == 6
    # a live process that _alive takes for an acquire job, recorded as run kx__ky
    dummy = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(120)",
                              "campaign.jobs.acquire"])
    try:
        (workspace / "kx__ky").mkdir()
        (workspace / ".gui" / "acquire").mkdir(parents=True)
        _record_path(workspace, workspace / "kx__ky").write_text(
            f'{{"run_dir": "kx__ky", "pid": {dummy.pid}, "events_file": "e", "log": "l"}}')
        r = client.post("/api/acquire/abort", json={"run": "kx/ky"})
        assert r.status_code == 404, r.text
        time.sleep(0.2)
        assert dummy.poll() is None  # no SIGINT reached it
        r = client.post("/api/acquire/abort", json={"run": "kx__ky"})
        assert r.status_code == 200 and r.json()["pid"] == dummy.pid
        assert dummy.wait(30) != 0  # the SIGINT ended it
    finally:
        with contextlib.suppress(OSError):
            os.kill(dummy.pid, signal.SIGKILL)
        dummy.wait()


#: a search of 441 placements in the server's process (about 2 s)
PLACE = {"robot": "kr240-2", "path": "part.csv", "x_mm": "1400..1800", "y_mm": "-200..200",
         "z_mm": "200", "x_step_mm": 20, "y_step_mm": 20, "tool_angle_step_deg": 30,
         "config": "-1,-1,-1", "workers": 0}


def test_the_scheduler_is_not_a_request_field(client, app, workspace):
    from tests.jobs.conftest import wait_job

    doc = client.get("/openapi.json").json()
    ref = doc["paths"]["/api/jobs/place"]["post"]["requestBody"]["content"][
        "application/json"]["schema"]["$ref"].rsplit("/", 1)[-1]
    props = doc["components"]["schemas"][ref]["properties"]
    assert "scheduler" not in props and "workers" in props
    app.state.jobs_in_threads = True
    shutil.copy(ROOT / "examples" / "part_circle.csv", workspace / "part.csv")
    with listener() as (port, connected):
        r = client.post("/api/jobs/place", json={**PLACE, "out": "p",
                                                 "scheduler": f"tcp://127.0.0.1:{port}"})
        assert r.status_code == 202, r.text
        job = wait_job(client, r.json()["id"])
        assert job["state"] == "done", job
        assert not connected()


def test_the_operator_chooses_the_scheduler(workspace):
    from campaign.web.app import create_app

    assert create_app(workspace, TOKEN, scheduler="tcp://127.0.0.1:8786").state.scheduler \
        == "tcp://127.0.0.1:8786"
    assert create_app(workspace, TOKEN).state.scheduler is None


def _save_robot(client, robot: str):
    return client.post("/api/plan/save", json={"source": "plan/protocol.toml",
                                               "name": "qa",
                                               "values": {"campaign.robot": robot}})


def test_plan_form_reads_no_robot_file_outside(client, workspace, tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret.toml").write_text('api_password = "hunter2"\n')
    shutil.copy(workspace / "robot.toml", outside / "robot.toml")  # a valid robot file
    answers = {}
    for robot in (str(outside / "secret.toml"), str(outside / "missing.toml"),
                  str(outside / "robot.toml"), "../../outside/secret.toml",
                  "../../outside/missing.toml", "../../outside/robot.toml"):
        r = _save_robot(client, robot)
        assert r.status_code == 400, (robot, r.text)
        assert r.json()["field"] == "campaign.robot", r.text
        assert "api_password" not in r.text and "not found" not in r.text, r.text
        answers[robot] = r.json()["detail"].replace(robot, "ROBOT")
    # the answers do not tell an existing file from a missing one
    assert len(set(answers.values())) == 2, answers  # absolute, '..'
    (workspace / "protocols").mkdir()
    (workspace / "protocols" / "link.toml").symlink_to(outside / "robot.toml")
    r = _save_robot(client, "link.toml")
    assert r.status_code == 400 and "symbolic link" in r.json()["detail"], r.text
    assert not (workspace / "protocols" / "qa.toml").exists()
    # the workspace's own robot file, named relative to protocols/ as the pickers name it
    r = _save_robot(client, "../robot.toml")
    assert r.status_code == 200, r.text


def test_one_path_rule_for_every_route(client, workspace):
    from fastapi import HTTPException

    from analysis.errors import InputError
    from campaign.web.api_jobs import inside
    from campaign.web.security import inside_workspace

    (workspace / "link.toml").symlink_to(workspace / "robot.toml")  # leads inside
    (workspace / "linkdir").symlink_to(workspace / "plan")
    for text in ("link.toml", "linkdir/plan.csv", "../x", "/etc", "plan/../../x", "~root", ".",
                 "C:/x", "a\x00b", "", "x" * 300, "plan/plan.csv", "new/dir", "robot.toml"):
        try:
            inside_workspace(workspace, text, "f")
            expected = None
        except InputError as err:
            expected = str(err)
        try:
            got = inside(workspace, text, "f")
            assert expected is None and got == workspace / text, text
        except HTTPException as err:
            assert err.status_code == 400 and err.detail == expected, text
    # through the jobs' routes as through the sensitivity explorer's
    r = client.post("/api/jobs/stiffness", json={"robot": "link.toml", "q_rad": [0] * 6})
    assert r.status_code == 400 and "symbolic link" in r.json()["detail"], r.text
    r = client.post("/api/jobs/acquire", json={"plan": "linkdir", "dry_run": True})
    assert r.status_code == 400 and "symbolic link" in r.json()["detail"], r.text


def test_pool_size_bound_same_line_as_the_cli(client, workspace):
    r = client.post("/api/jobs/robustness", json={"robot": "kr240-2", "trials": 10,
                                                  "tests": [5], "pool_size": 10**9})
    assert r.status_code == 400, r.text
    line = cli_error(workspace, "robustness", "--robot", "kr240-2", "--pool-size", str(10**9),
                     "--trials", "10",
                     "--tests", "5")
    assert r.json()["detail"] == line == "--pool-size: expected at most 1000000 poses, got " \
        "1000000000"
    assert r.json()["field"] == "pool_size"


def test_time_scale_bound_same_line_as_the_cli(client, workspace):
    r = client.post("/api/jobs/acquire", json={"plan": "plan", "out": "r", "fake": True,
                                               "assume_yes": True, "time_scale": 1e308})
    assert r.status_code == 400, r.text
    line = cli_error(workspace, "acquire", "--plan", "plan", "--out", "r", "--fake", "--yes",
                     "--time-scale", "1e308")
    assert r.json()["detail"] == line == "--time-scale: expected at most 10000, got 1e+308"
    assert not (workspace / "r").exists()
    # the Acquire view's own form has the same bound
    r = client.post("/api/acquire/start", json={"plan": "plan", "out": "r",
                                                "time_scale": 1e308})
    assert r.status_code == 422 and "10000" in r.text


def test_a_body_over_the_limit_is_413_unread(client):
    from campaign.web.app import MAX_BODY_BYTES

    big = b'{"name": "a.urdf", "text": "' + b"x" * MAX_BODY_BYTES + b'"}'
    r = client.post("/api/robots/urdf", content=big,
                    headers={"Content-Type": "application/json"})
    assert r.status_code == 413, r.text[:200]

    def chunks():  # no Content-Length: counted as it arrives
        yield b'{"name": "a.urdf", "text": "'
        for _ in range(MAX_BODY_BYTES // 2**20 + 2):
            yield b"x" * 2**20
        yield b'"}'

    r = client.post("/api/robots/urdf", content=chunks(),
                    headers={"Content-Type": "application/json"})
    assert r.status_code == 413, r.text[:200]
    assert str(MAX_BODY_BYTES) in client.get("/openapi.json").json()["info"]["description"]


def test_the_ledger_is_not_a_request_choice(client, app, workspace, analyses):
    """A client naming a ledger URL in /api/jobs/analyze makes the server open nothing:
    the analysis records into the operator's ledger (here none) or nowhere."""
    from tests.jobs.conftest import wait_job

    csv = analyses[0].parent / "A.csv"
    shutil.copy(csv, workspace / "A.csv")
    app.state.jobs_in_threads = True
    theirs = workspace / "theirs.db"
    with listener() as (port, connected):
        for url in (f"postgresql+psycopg://u:p@127.0.0.1:{port}/x", f"sqlite:///{theirs}"):
            r = client.post("/api/jobs/analyze", json={
                "measurements": "A.csv", "robot": "kr240-2", "out": f"a{len(url)}",
                "report": False, "translation_sigma_um": 20.0, "ledger": url,
                "accept_misfit": True})
            assert r.status_code == 202, r.text
            job = wait_job(client, r.json()["id"])
            assert job["state"] == "done", job
            assert "ledger" not in job["result"]
        assert not connected()
    assert not theirs.exists()
