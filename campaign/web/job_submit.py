"""Queued jobs over HTTP: submitting one (202 or 429), its state, events and cancellation.

:func:`submit` is what a POST of a long job of ``/api/jobs`` (see
:mod:`campaign.web.api_jobs`) calls once the request is checked: the job goes to
the application's :class:`~campaign.web.job_queue.JobQueue` (``app.state.jobs``,
made on first use), its refusal becomes the error record of
:func:`campaign.web.job_errors.describe`, and an output directory it created is
removed if it fails or is cancelled. :data:`router` (no prefix: included by the
jobs router) serves ``GET /{job_id}``, ``GET /{job_id}/events`` (server-sent
events), ``DELETE /{job_id}`` and ``POST /{job_id}/cancel``.
"""

from __future__ import annotations

import asyncio
import json
import os
import shutil
import threading
from collections.abc import Callable
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Literal

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse, StreamingResponse
from pydantic import BaseModel

from campaign.jobs.choices import json_ready
from campaign.web.job_process import ProcessFailed, run_in_process, run_in_thread
from campaign.web.job_queue import FINAL, JobQueue, Progress, QueueFull

router = APIRouter()

#: jobs run at a time by one server (two cores: the other one serves the page, and the
#: placement search's Dask workers share both), and jobs that may wait behind them
JOB_WORKERS = 1
JOB_WAITING = 2


class Reason(BaseModel):
    """One reason the data do not support a result (:class:`analysis.errors.Refusal`)."""

    text: str


class JobError(BaseModel):
    """A queued job's refusal (see :func:`campaign.web.job_errors.describe`); ``refused``:
    the reasons of a result the data do not support (the analyze job), one each;
    ``problems``: a form's refusal, each line with the form field it names (the Plan view)."""

    status: int
    detail: str
    field: str | None = None
    options: dict[str, str] = {}
    refused: list[Reason] | None = None
    problems: list[dict] | None = None


class JobState(BaseModel):
    """A queued job as ``GET /api/jobs/{job_id}`` gives it (times: s since the epoch)."""

    id: str
    kind: str
    state: Literal["queued", "running", "done", "failed", "cancelled"]
    fraction: float | None = None
    text: str
    result: dict | None = None
    error: JobError | None = None
    created: float
    started: float | None = None
    finished: float | None = None


class Refusal(BaseModel):
    """A refused request: the one line, the request field at fault, the options it names."""

    detail: str
    field: str | None = None
    options: dict[str, str] = {}


#: the answers of a queued job's POST, for the OpenAPI document
QUEUED = {202: {"model": JobState, "description": "queued: the job (follow GET "
                "/api/jobs/{job_id} or its events)"},
          400: {"model": Refusal, "description": "refused: bad input or above a bound"},
          429: {"model": Refusal, "description": "the job queue is full"}}


_QUEUE_LOCK = threading.Lock()


def job_queue(request: Request) -> JobQueue:
    """The application's job queue (``app.state.jobs``), made on first use with
    :data:`JOB_WORKERS` and :data:`JOB_WAITING` unless the application set its own."""
    state = request.app.state
    with _QUEUE_LOCK:
        queue = getattr(state, "jobs", None)
        if queue is None:
            queue = state.jobs = JobQueue(JOB_WORKERS, JOB_WAITING, describe_error=_record)
    return queue


def _record(err: BaseException) -> dict | None:
    return err.record if isinstance(err, JobFailed) else None


class JobFailed(Exception):
    """A job's refusal, carrying its error record (see :func:`describe`)."""

    def __init__(self, record: dict) -> None:
        super().__init__(record["detail"])
        self.record = record


def submit(request: Request, ws: Path, kind: str, options, task: Callable[..., Any],
           extra: tuple = (), cleanup: bool = True) -> JSONResponse:
    """Queue ``task(progress, options, *extra)`` (a module-level function of
    :mod:`campaign.web.job_tasks`, run in a process of its own: :mod:`job_process`);
    202 with the job, or 429 when the queue is full.

    With ``cleanup``, a job that fails or is cancelled leaves no output directory it
    created (as :func:`analysis.output_files.created_dir`: what did not exist before is
    removed, once its process has ended); an acquisition keeps its run (the record of
    what moved, resumable)."""
    out = getattr(options, "out", None) if cleanup else None
    # the application may run its jobs in the queue's threads (tests: no start-up time)
    runner = run_in_thread if getattr(request.app.state, "jobs_in_threads", False) \
        else run_in_process

    def job(progress: Progress) -> dict:
        with _removed_on_failure(None if out is None else Path(out), ws):
            try:
                return runner(task, ws, options, progress, extra)
            except ProcessFailed as err:
                raise JobFailed(err.record or {"status": 500, "detail": str(err),
                                               "field": None, "options": {}}) from None

    try:
        queued = job_queue(request).submit(kind, job)
    except QueueFull as err:
        return JSONResponse({"detail": str(err)}, status_code=429)
    return JSONResponse(queued.public(), status_code=202,
                        headers={"Location": f"/api/jobs/{queued.id}"})


@contextmanager
def _removed_on_failure(out: Path | None, ws: Path):
    """Remove ``out`` and the parents this job made when the body fails (inside ``ws``)."""

    top = None
    if out is not None and out.is_relative_to(ws):
        for p in (out, *out.parents):
            if p == ws or os.path.lexists(p):
                break
            top = p
    try:
        yield
    except BaseException:
        if top is not None and not top.is_symlink():
            shutil.rmtree(top, ignore_errors=True)
        raise


@router.get("/{job_id}", response_model=JobState, responses={404: {"model": Refusal}})
def job_state(job_id: str, request: Request) -> JSONResponse:
    """A queued job: ``state`` (queued, running, done, failed, cancelled), ``fraction``
    (0..1, null: unknown) and ``text`` of its progress, ``result`` (done) or ``error``
    (failed: ``status``, the one line ``detail``, the request ``field`` at fault and the
    command-line ``options`` the line names, mapped to request fields)."""
    job = job_queue(request).get(job_id)
    if job is None:
        return JSONResponse({"detail": f"job_id: no job {job_id[:80]!r} on this server "
                             "(finished jobs are forgotten after a while)"}, status_code=404)
    return JSONResponse(job.public())


@router.get("/{job_id}/events")
async def job_events(job_id: str, request: Request):
    """Server-sent events of a job: one ``data:`` (the job's state, as GET /api/jobs/{id})
    per change, every change from its submission (the last 1000), then ``event: end``
    once it has ended."""


    queue = job_queue(request)
    if queue.get(job_id) is None:
        return JSONResponse({"detail": f"job_id: no job {job_id[:80]!r} on this server"},
                            status_code=404)

    async def stream():
        version = 0
        while True:
            job = queue.get(job_id)
            if job is None:
                yield "event: end\ndata: {}\n\n"
                return
            with queue.lock:
                states = job.since(version)
            for _, state in states:
                yield f"data: {json.dumps(json_ready(state))}\n\n"
            if states:
                version = states[-1][0]
            if states and states[-1][1]["state"] in FINAL:
                yield "event: end\ndata: {}\n\n"
                return
            if await request.is_disconnected():
                return
            await asyncio.sleep(0.1)

    return StreamingResponse(stream(), media_type="text/event-stream",
                             headers={"Cache-Control": "no-store"})


@router.delete("/{job_id}", response_model=JobState,
                responses={404: {"model": Refusal}})
def job_cancel(job_id: str, request: Request) -> JSONResponse:
    """Cancel a job: a queued one at once, a running one at its next progress step (its
    outputs removed, as a failed command leaves none); a finished job stays as it ended."""
    job = job_queue(request).cancel(job_id)
    if job is None:
        return JSONResponse({"detail": f"job_id: no job {job_id[:80]!r} on this server"},
                            status_code=404)
    return JSONResponse(job.public())


@router.post("/{job_id}/cancel", response_model=JobState,
             responses={404: {"model": Refusal}})
def job_cancel_post(job_id: str, request: Request) -> JSONResponse:
    """The same as DELETE /api/jobs/{job_id}, for clients that only POST."""
    return job_cancel(job_id, request)
