"""``/api/acquire``: the Acquire view's acquisition, run in a process of its own.

``POST /dry-run`` lists the motions as ``campaign acquire --dry-run`` does (nothing
connected, nothing moved). ``POST /start`` checks the plan the same way (the dry run is
the preflight), then starts ``python -m campaign.jobs.acquire OPTIONS.json`` in a new
session (detached: closing the page or stopping the server does not stop it) and
answers at once. ``POST /resume`` continues a partial run; ``POST /abort`` sends SIGINT
(the Ctrl-C path: motion stopped, load removed, ``aborted`` recorded).

The server keeps nothing in memory that its files do not hold: the job's record (run
directory, pid, events file) is ``.gui/acquire/<name>.json`` in the workspace, so any tab
and a restarted server reattach through ``GET /state`` (the run directory read again, the
events file from where this server last stopped reading it) and ``GET /events``
(server-sent events: the events file's JSON lines as they are written).
Only the simulated lab starts without ``confirm``; a real robot needs ``confirm: true``
(the CLI's safety question answered), as ``campaign acquire --yes``.
"""

from __future__ import annotations

import asyncio
import contextlib
import fcntl
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

from fastapi import APIRouter, Depends, HTTPException, Query, Request
from fastapi.responses import Response, StreamingResponse
from pydantic import BaseModel, Field

from campaign.web.api_jobs import call, inside, workspace

router = APIRouter(prefix="/api/acquire", tags=["acquire"])
#: where the job records live, inside the workspace
JOBS = Path(".gui") / "acquire"
#: live fields of the progress lines kept as the current state
LIVE = ("phase", "test_id", "repeat", "attempt", "pose", "done", "total", "wrench",
        "wrench_planned", "deflection_mm", "elapsed_s", "remaining_s")
#: tests.csv columns shown per finished test (SI scaled at the edge: um, urad)
ROW_FIELDS = ("test_id", "repeat", "status", "flags", "fx_N", "fy_N", "fz_N", "mx_Nm",
              "my_Nm", "mz_Nm", "dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad",
              "repeatability_mm")
#: the runner's phases grouped into the view's stages of a test
STAGES = {"approach": "approach", "move": "approach", "settle_unloaded_before": "tare",
          "tare": "tare", "unloaded_before": "tare", "apply_load": "load",
          "settle_loaded": "settle", "loaded": "measure", "remove_load": "unload",
          "settle_unloaded_after": "unload", "unloaded_after": "unload",
          # a preloaded load case: the reference readings under the preload
          "apply_preload_before": "tare", "settle_reference_before": "tare",
          "reference_before": "tare", "apply_preload_after": "unload",
          "settle_reference_after": "unload", "reference_after": "unload"}
_children: dict[int, subprocess.Popen] = {}  # reaped here while this server lives
#: one check-then-spawn at a time (two tabs starting the same run at once)
_starting = threading.Lock()


class DryRunRequest(BaseModel):
    """plan: plan directory (relative to the workspace); or resume: a partial run."""
    plan: str | None = Field(None, max_length=1000)
    resume: str | None = Field(None, max_length=1000)


class StartRequest(BaseModel):
    """plan and out (a new run directory), relative to the workspace; fake: the simulated
    lab; time_scale: its clock runs that much faster; confirm: the safety question
    answered (required for a real robot); operator: recorded in the metadata."""
    plan: str = Field(..., max_length=1000)
    out: str = Field(..., max_length=1000)
    fake: bool = True
    time_scale: float | None = Field(None, gt=0, le=10000)
    confirm: bool = False
    operator: str | None = Field(None, max_length=200)


class ResumeRequest(BaseModel):
    """run: a partial run directory (relative to the workspace)."""
    run: str = Field(..., max_length=1000)
    fake: bool = True
    time_scale: float | None = Field(None, gt=0, le=10000)
    confirm: bool = False


class RunRequest(BaseModel):
    run: str = Field(..., max_length=1000)


def _key(ws: Path, run_dir: Path) -> str:
    return str(run_dir.relative_to(ws)).replace("/", "__")


def _record_path(ws: Path, run_dir: Path) -> Path:
    return ws / JOBS / f"{_key(ws, run_dir)}.json"


def _alive(pid: int | None) -> bool:
    """``pid`` is a running (not zombie) acquire job."""
    if not pid:
        return False
    child = _children.get(pid)
    if child is not None and child.poll() is not None:
        _children.pop(pid, None)
        return False
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False
    return stat.rsplit(")", 1)[-1].split()[0] != "Z" and b"campaign.jobs.acquire" in cmdline


def _locked(run_dir: Path) -> bool:
    """Another process holds the run's lock (it is being written)."""
    from campaign.acquire.rundir import LOCK

    try:
        fd = os.open(run_dir / LOCK, os.O_RDWR)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    except OSError:
        return True
    finally:
        os.close(fd)


class _Done:
    """A check's (empty) result for :func:`campaign.web.api_jobs.call`."""

    def __init__(self, _value=None) -> None:
        pass

    def to_json(self) -> dict:
        return {}


def _dry_run(ws: Path, plan: Path | None, resume: Path | None, fake: bool = True) -> list[str]:
    """The motion list of the CLI's --dry-run; InputError (400) on a bad plan."""
    from campaign.jobs.acquire import AcquireJobOptions, run

    lines: list[str] = []
    result = call(ws, lambda: run(AcquireJobOptions(plan=plan, resume=resume, fake=fake,
                                                    dry_run=True),
                                  say=lambda s: lines.extend(str(s).splitlines())))
    status = json.loads(result.body)["status"]
    if status != "dry-run":
        raise HTTPException(400, f"dry run: {status}")
    return lines


@router.post("/dry-run")
def dry_run(req: DryRunRequest, ws: Path = Depends(workspace)) -> dict:
    """The motions of the plan (or of a partial run's remaining tests); nothing moves."""
    if (req.plan is None) == (req.resume is None):
        raise HTTPException(400, "give plan or resume (one of them)")
    plan = None if req.plan is None else inside(ws, req.plan, "plan")
    resume = None if req.resume is None else inside(ws, req.resume, "resume")
    return {"motions": _dry_run(ws, plan, resume)}


def _spawn(ws: Path, run_dir: Path, options) -> dict:
    """Start the job detached; its record into the workspace."""
    import dataclasses

    jobs = ws / JOBS
    jobs.mkdir(parents=True, exist_ok=True)
    key = _key(ws, run_dir)
    stamp = time.strftime("%Y%m%d-%H%M%S", time.gmtime())
    events = jobs / f"{key}.{stamp}.{time.time_ns() % 10**9}.events.jsonl"
    events.touch()
    options = dataclasses.replace(options, events_file=events)
    opt_file = events.with_suffix("").with_suffix(".options.json")
    opt_file.write_text(json.dumps(options.to_dict()))
    log = open(events.with_suffix("").with_suffix(".log"), "w")  # noqa: SIM115
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "campaign.jobs.acquire", str(opt_file)],
                            cwd=ws, stdin=subprocess.DEVNULL, stdout=log, stderr=log,
                            start_new_session=True, close_fds=True, env=env)
    log.close()
    _children[proc.pid] = proc
    record = {"run_dir": str(run_dir.relative_to(ws)), "pid": proc.pid,
              "events_file": str(events.relative_to(ws)), "log": str(
                  Path(log.name).relative_to(ws)), "started_utc": stamp,
              "fake": options.fake}
    tmp = _record_path(ws, run_dir).with_suffix(".tmp")
    tmp.write_text(json.dumps(record))
    tmp.replace(_record_path(ws, run_dir))
    (jobs / "latest").write_text(record["run_dir"])
    return record


def _check_safety(fake: bool, confirm: bool, hardware: bool) -> None:
    if not fake and not hardware:
        raise HTTPException(403, "hardware: this GUI server was started without --hardware, "
                                 "so it runs acquisitions on the simulated lab only (restart "
                                 "it with `campaign gui --hardware` to drive a real robot)")
    if not fake and not confirm:
        raise HTTPException(400, "confirmation: the robot WILL move; a run on hardware needs "
                                 "confirm: true (the CLI's --yes)")


@router.post("/start")
def start(req: StartRequest, request: Request, ws: Path = Depends(workspace)) -> dict:
    """Preflight (the dry run), then start a new run in its own process; answers at once."""
    _check_safety(req.fake, req.confirm, request.app.state.hardware)
    plan, out = inside(ws, req.plan, "plan"), inside(ws, req.out, "out")
    with _starting:
        return _start(ws, req, plan, out)


def _start(ws: Path, req: StartRequest, plan: Path, out: Path) -> dict:
    from campaign.acquire.rundir import require_new_run_dir
    from campaign.jobs.acquire import AcquireJobOptions

    if _record_path(ws, out).exists() and _alive(_read(ws, out).get("pid")):
        raise HTTPException(409, f"{req.out}: an acquisition is writing this run")
    call(ws, lambda: _Done(require_new_run_dir(out)))
    _dry_run(ws, plan, None, req.fake)
    options = AcquireJobOptions(plan=plan, out=out, fake=req.fake, assume_yes=True,
                                time_scale=req.time_scale, operator=req.operator)
    return _spawn(ws, out, options)


@router.post("/resume")
def resume(req: ResumeRequest, request: Request, ws: Path = Depends(workspace)) -> dict:
    """Continue a partial run from its first unfinished test, in its own process."""
    _check_safety(req.fake, req.confirm, request.app.state.hardware)
    run_dir = inside(ws, req.run, "run")
    with _starting:
        return _resume(ws, req, run_dir)


def _resume(ws: Path, req: ResumeRequest, run_dir: Path) -> dict:
    from campaign.jobs.acquire import AcquireJobOptions

    if not (run_dir / "metadata.json").is_file():
        raise HTTPException(400, f"run: {req.run!r} is not a run directory (no metadata.json)")
    if _alive(_read(ws, run_dir).get("pid")) or _locked(run_dir):
        raise HTTPException(409, f"{req.run}: an acquisition is writing this run (its lock "
                                 "is held)")
    _dry_run(ws, None, run_dir, req.fake)
    options = AcquireJobOptions(resume=run_dir, fake=req.fake, assume_yes=True,
                                time_scale=req.time_scale)
    return _spawn(ws, run_dir, options)


def _read(ws: Path, run_dir: Path) -> dict:
    try:
        return json.loads(_record_path(ws, run_dir).read_text())
    except (OSError, ValueError):
        return {}


def _run_of(ws: Path, run: str | None) -> Path:
    if run is None:
        try:
            run = (ws / JOBS / "latest").read_text().strip()
        except OSError:
            raise HTTPException(404, "no acquisition started from this workspace") from None
    return inside(ws, run, "run")


def _rows(run_dir: Path) -> list[dict]:
    import csv

    try:
        with open(run_dir / "tests.csv", newline="", encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
    except OSError:
        return []

    def num(v):
        try:
            return float(v)
        except (TypeError, ValueError):
            return v

    return [{k: num(r.get(k)) for k in ROW_FIELDS} for r in rows]


@router.get("/state", responses={204: {"description": "no acquisition started from this "
                                               "workspace yet (no run asked for)"}})
def state(request: Request, run: str | None = Query(None, max_length=1000),
          ws: Path = Depends(workspace)) -> dict:
    """The run's state from its files: running or not, the live phase, finished tests.
    Without ``run`` and before any acquisition: 204, the page's usual first question and no
    error (a 404 would log one in the browser's console on every fresh page).

    The events file is read from where this server's last reading of it stopped
    (:mod:`campaign.web.events_tail`), with the answer of a full reading."""
    from campaign.web.events_tail import EventsSummary, tails_of

    if run is None and not (ws / JOBS / "latest").is_file():
        return Response(status_code=204)
    run_dir = _run_of(ws, run)
    record = _read(ws, run_dir)
    summary = tails_of(request.app, LIVE).read(ws / record["events_file"]) if record \
        else EventsSummary()
    live, start_info, finish = summary.live, summary.start, summary.finish
    meta = {}
    with contextlib.suppress(OSError, ValueError):
        meta = json.loads((run_dir / "metadata.json").read_text())
    running = _alive(record.get("pid"))
    log = ""
    if record and not running and finish is None:
        with contextlib.suppress(OSError):
            log = (ws / record["log"]).read_text()[-2000:].strip()
    return {"run_dir": str(run_dir.relative_to(ws)), "running": running,
            "pid": record.get("pid"), "status": meta.get("status"),
            "reason": meta.get("reason", ""), "live": live,
            "stage": STAGES.get(live.get("phase"), live.get("phase")),
            "total": live.get("total", start_info.get("total")),
            "finish": finish, "tests": _rows(run_dir), "log": log}


@router.get("/events")
async def events(run: str | None = Query(None, max_length=1000),
                 offset: int = Query(0, ge=0, le=2**62), ws: Path = Depends(workspace)):
    """Server-sent events: the events file's new lines (``id``: byte offset after each);
    the stream ends when the job has ended and every line is sent."""
    run_dir = _run_of(ws, run)
    record = _read(ws, run_dir)
    if not record:
        raise HTTPException(404, f"{run_dir.relative_to(ws)}: no acquisition started here")
    path = ws / record["events_file"]

    async def stream():
        pos = offset
        idle = 0
        while True:
            try:
                with open(path, "rb") as f:
                    f.seek(pos)
                    chunk = f.read()
            except OSError:
                chunk = b""
            end = chunk.rfind(b"\n")
            if end >= 0:
                for line in chunk[:end].splitlines():
                    pos += len(line) + 1
                    yield f"id: {pos}\ndata: {line.decode('utf-8', 'replace')}\n\n"
                idle = 0
            elif not _alive(record["pid"]):
                yield "event: end\ndata: {}\n\n"
                return
            else:
                idle += 1
                if idle % 50 == 0:
                    yield ": keep-alive\n\n"
            await asyncio.sleep(0.1)

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-store"})


@router.post("/abort")
def abort_run(req: RunRequest, ws: Path = Depends(workspace)) -> dict:
    """SIGINT to the run's job: Ctrl-C's path (load removed, robot stopped, recorded)."""
    from campaign.jobs.acquire import abort

    run_dir = inside(ws, req.run, "run")
    pid = _read(ws, run_dir).get("pid")
    if not _alive(pid):
        raise HTTPException(409, f"{req.run}: no acquisition is running")
    abort(pid)
    return {"run_dir": req.run, "pid": pid, "signal": "SIGINT"}
