"""``POST /api/jobs/demo``: the demo job (plan, acquire on the simulated lab, analyze).

Kept beside :mod:`campaign.web.api_jobs` (same prefix, same path checks and
error mapping: :func:`~campaign.web.api_jobs.inside`, :func:`~campaign.web.api_jobs.call`)
so that the jobs router is not edited by two engineers at once. The body is
:class:`campaign.jobs.demo.DemoOptions` (paths relative to the workspace), the
answer the document ``campaign demo --json`` prints. Only the simulated lab is
started: nothing real moves.
"""

import dataclasses  # no "from __future__ import annotations": FastAPI reads the hints
from pathlib import Path

from fastapi import APIRouter, Depends
from fastapi.responses import JSONResponse

from campaign.jobs.demo import DemoOptions
from campaign.web.api_jobs import call, inside, workspace

router = APIRouter(prefix="/api/jobs", tags=["jobs"])


@router.post("/demo")
def demo(options: DemoOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """Plan, acquire on the simulated lab and analyse into ``out`` (``OUT/plan``, ``OUT/run``,
    ``OUT/run/analysis``); answers when the analysis is written (tens of seconds)."""
    from campaign.jobs.demo import run

    options = dataclasses.replace(
        options, out=inside(ws, options.out, "out"),
        protocol=None if options.protocol is None else inside(ws, options.protocol,
                                                               "protocol"))
    return call(ws, lambda: run(options))
