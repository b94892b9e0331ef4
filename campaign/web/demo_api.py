"""``POST /api/jobs/demo``: the demo job (plan, acquire on the simulated lab, analyze), queued.

Kept beside :mod:`campaign.web.api_jobs` (same prefix, same path checks and queue:
:func:`~campaign.web.api_jobs.inside`, :func:`~campaign.web.job_submit.submit`) so
that the jobs router is not edited by two engineers at once. The body is
:class:`campaign.jobs.demo.DemoOptions` (paths relative to the workspace); the
answer is 202 with the job, whose result is the document ``campaign demo --json``
prints. Only the simulated lab is started: nothing real moves. A cancelled demo
takes the acquisition's Ctrl-C path, and leaves no output directory it created.
"""

import dataclasses  # no "from __future__ import annotations": FastAPI reads the hints
from pathlib import Path

from fastapi import APIRouter, Depends, Request
from fastapi.responses import JSONResponse

from campaign.jobs.demo import DemoOptions
from campaign.web.api_jobs import inside, workspace
from campaign.web.job_submit import QUEUED, submit

router = APIRouter(prefix="/api/jobs", tags=["jobs"])


def demo_task(progress, options):
    """The demo in the job's process: its steps, the acquisition's phases and the
    analysis' warnings as progress; a cancellation takes the acquisition's Ctrl-C path."""
    from campaign.jobs.demo import run
    from campaign.web import progress_hooks
    from campaign.web.job_queue import JobCancelled

    result = run(options, say=progress_hooks.say(progress),
                 stage=progress_hooks.stage(progress),
                 reporter=progress_hooks.AcquireProgress(progress),
                 warn=progress_hooks.say(progress), should_abort=progress.cancelled)
    if progress.cancelled():
        raise JobCancelled(f"cancelled: the acquisition was stopped (motion stopped, load removed) "
                           f"({result.acquisition.status}: {result.acquisition.reason})")
    return result


@router.post("/demo", status_code=202, responses=QUEUED)
def demo(options: DemoOptions, request: Request,
         ws: Path = Depends(workspace)) -> JSONResponse:
    """Plan, acquire on the simulated lab and analyse into ``out`` (``OUT/plan``, ``OUT/run``,
    ``OUT/run/analysis``); queued (202 with the job, tens of seconds)."""
    options = dataclasses.replace(
        options, out=inside(ws, options.out, "out"),
        protocol=None if options.protocol is None else inside(ws, options.protocol,
                                                               "protocol"))
    return submit(request, ws, "demo", options, demo_task)
