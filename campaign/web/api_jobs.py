"""``/api/jobs``: one POST endpoint per job of :mod:`campaign.jobs`, and the job queue.

The long jobs (plan, acquire, analyze, maps, robustness, compensate, place) are
queued (:mod:`campaign.web.job_submit`; each runs in a process of its own,
:mod:`campaign.web.job_tasks`): the POST checks the request (paths, this
server's bounds on trials, candidates, evaluations and map points: 400 naming
the limit), answers 202 with the job (``id``, ``state``...; 429 when the queue is
full), and ``GET /api/jobs/{id}`` gives its state, progress, result or error
(``/events``: the same as server-sent events; ``DELETE`` or ``POST .../cancel``
stops it, its outputs removed). robots, stiffness, compare and export answer at once.

Request bodies are the jobs' options records themselves (FastAPI reads the
dataclasses), so the units are the records' SI units (radians, N, N m, m),
not the degrees and millimetres the command line takes at its edge; a tool
point is given as the protocol's ``[tool]`` table gives it (mm, deg), and the
field names say so. Responses are the result records as JSON, the same
documents the command's ``--json`` prints (NaN and infinities as null).

Every path in a body is relative to the workspace (``request.app.state.workspace``):
an absolute path, a ``..`` part, or a symbolic link is refused with 400 and one
line (the web's one path rule, :func:`campaign.web.security.inside_workspace`).
The jobs get absolute paths, so the files they write name workspace files by
absolute path where the command line would write the path as typed; the JSON
answers give them relative to the workspace. Bad input gets 400 (or 422 from the body's
schema) with the same one-line message as the command line, with the request
field at fault and the command-line options the line names
(:mod:`campaign.web.job_errors`); a refused write (disk full, permissions) is
409 with the file named. A queued job's refusal is the same record, as its
``error``.
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from fastapi import APIRouter, Depends, HTTPException, Request
from fastapi.responses import JSONResponse

from campaign.jobs.acquire import AcquireJobOptions
from campaign.jobs.analyze import AnalyzeOptions
from campaign.jobs.choices import json_ready
from campaign.jobs.compare import CompareOptions
from campaign.jobs.compensate import CompensateOptions
from campaign.jobs.export import ExportOptions
from campaign.jobs.maps import MapsOptions
from campaign.jobs.place import PlaceOptions
from campaign.jobs.plan import PlanOptions
from campaign.jobs.robots import RobotsOptions
from campaign.jobs.robustness import RobustnessOptions
from campaign.jobs.stiffness import StiffnessOptions
from campaign.use.place_run import DEFAULT_MAX_EVALUATIONS
from campaign.web import job_tasks
from campaign.web.job_errors import describe, relative_to_workspace
from campaign.web.job_submit import QUEUED, Refusal, submit
from campaign.web.job_submit import router as queue_router

#: per request: robustness' simulated campaigns (trials x numbers of tests; the default
#: study is 20 000), plan's candidate poses, place's evaluations, maps' grid points
MAX_CAMPAIGNS = 100_000
MAX_CANDIDATES = 100_000
MAX_EVALUATIONS = DEFAULT_MAX_EVALUATIONS
MAX_MAP_POINTS = 4_000_000

router = APIRouter(prefix="/api/jobs", tags=["jobs"])


def workspace(request: Request) -> Path:
    """The workspace directory of the application (``app.state.workspace``), resolved."""
    ws = getattr(request.app.state, "workspace", None)
    if ws is None:
        raise HTTPException(500, "the application has no workspace directory")
    return Path(ws).resolve()


def inside(ws: Path, rel: str | Path, field: str) -> Path:
    """``rel`` (relative to the workspace) as an absolute path inside it, by the web's one
    path rule (:func:`campaign.web.security.inside_workspace`: no absolute path, no
    ``..``, no symbolic link); its refusal as 400 naming ``field``."""
    from analysis.errors import InputError
    from campaign.web.security import inside_workspace

    try:
        return inside_workspace(ws, rel, field)
    except InputError as err:
        raise HTTPException(400, str(err)) from None  # "field: the one line"


def call(ws: Path | None, job: Callable[[], Any]) -> JSONResponse:
    """Run ``job()``; its result record as JSON, or bad input raised as HTTPException
    (400/409) with its one line (for the routes that answer errors as FastAPI does)."""
    answered = answer(ws, job)
    if answered.status_code >= 400:
        raise HTTPException(answered.status_code, json.loads(answered.body)["detail"])
    return answered


def answer(ws: Path | None, job: Callable[[], Any], options=None,
           present: Callable[[Any], Any] | None = None) -> JSONResponse | None:
    """Run ``job()`` here and now; its result record as JSON, or a refusal as 400/409
    with its one line, the request field at fault and the options it names
    (:func:`campaign.web.job_errors.describe`). ``present(result)`` instead of the
    record's JSON (its value is returned as it is: None for a check that passed)."""
    try:
        result = job()
    except Exception as err:
        error = describe(err, ws, options)
        if error is None:
            raise
        return JSONResponse({k: v for k, v in error.items() if k != "status"},
                            status_code=error["status"])
    if present is not None:
        return present(result)
    doc = json_ready(result.to_json())
    return JSONResponse(doc if ws is None else relative_to_workspace(ws, doc))


def bound_error(field: str, text: str) -> JSONResponse:
    """400 for a request above one of this server's bounds, the bound named."""
    return JSONResponse({"detail": f"{field}: {text}", "field": field, "options": {}},
                        status_code=400)


def map_points(step_rad: float) -> float | None:
    """Grid points of a (theta_2, theta_3) map at ``step_rad`` over a full turn each (an
    upper bound of the robot's own ranges); None for a step that is not positive."""
    import math

    if not (math.isfinite(step_rad) and step_rad > 0):
        return None
    per_axis = 2 * math.pi / step_rad + 1  # finite: step_rad >= the smallest float
    return per_axis * per_axis if per_axis < 1e150 else math.inf  # no OverflowError


def robot_path(ws: Path, robot: str, field: str = "robot") -> str:
    """A robot given by name stays a name; one given as a file is a workspace path (a
    URDF may carry its tool frame, ``FILE.urdf#FRAME``: analysis.model.robot_spec)."""
    from analysis.model.robot_spec import is_robot_file, split_urdf_spec

    if is_robot_file(robot):
        path, frame = split_urdf_spec(robot.strip())
        return str(inside(ws, path, field)) + (f"#{frame}" if frame else "")
    return robot  # a built-in name (an unknown one is refused by the job, naming the field)


@router.post("/robots")
def robots(options: RobotsOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """The built-in robot models (no name), or one model (SI units, radians)."""
    from campaign.jobs.robots import run

    if options.name is not None:
        options = dataclasses.replace(options, name=robot_path(ws, options.name, "name"))
    return answer(ws, lambda: run(options), options)


@router.post("/stiffness")
def stiffness(options: StiffnessOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """J, K_C, K_X and the deflection at one pose (q in rad, k in N m/rad, wrench N, N m)."""
    from campaign.jobs.stiffness import run

    options = dataclasses.replace(options, robot=robot_path(ws, options.robot))
    return answer(ws, lambda: run(options), options)


@router.post("/plan", status_code=202, responses=QUEUED)
def plan(options: PlanOptions, request: Request,
         ws: Path = Depends(workspace)) -> JSONResponse:
    """Plan the tests of a protocol file into the plan directory ``out`` (workspace paths);
    queued (202 with the job; ``candidates`` at most :data:`MAX_CANDIDATES`)."""

    if options.candidates > MAX_CANDIDATES:
        return bound_error("candidates", f"{options.candidates} candidate poses, above this "
                           f"server's limit of {MAX_CANDIDATES} per request")
    options = dataclasses.replace(options, protocol=inside(ws, options.protocol, "protocol"),
                                  out=inside(ws, options.out, "out"))
    return submit(request, ws, "plan", options, job_tasks.plan)


@router.post("/maps", status_code=202, responses=QUEUED)
def maps(options: MapsOptions, request: Request,
         ws: Path = Depends(workspace)) -> JSONResponse:
    """The paper's Figs. 3 and 5 maps into ``out`` (grid step and fixed joints in rad);
    queued (202 with the job; at most :data:`MAX_MAP_POINTS` grid points)."""

    points = map_points(options.step_rad)  # None: a step the job itself refuses
    if points is not None and points > MAX_MAP_POINTS:
        return bound_error("step_rad", f"a step of {options.step_rad:g} rad gives up to "
                           f"{points:.3g} "
                           f"grid points, above this server's limit of {MAX_MAP_POINTS:.3g} "
                           "per request: a coarser step")
    options = dataclasses.replace(options, robot=robot_path(ws, options.robot),
                                  out=inside(ws, options.out, "out"))
    return submit(request, ws, "maps", options, job_tasks.maps)


@router.post("/compare")
def compare(options: CompareOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """k_B - k_A per joint with its interval, z score and verdict (campaign paths a and b);
    answered at once (a comparison takes milliseconds)."""
    from campaign.jobs.compare import run

    options = dataclasses.replace(
        options, a=inside(ws, options.a, "a"), b=inside(ws, options.b, "b"),
        plot=None if options.plot is None else inside(ws, options.plot, "plot"),
        report=None if options.report is None else inside(ws, options.report, "report"))
    return answer(ws, lambda: run(options), options)


@router.post("/export")
def export(options: ExportOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """The robot as an MJCF, URDF or SDF file ``out`` with its joint springs (workspace
    paths); answered at once (writing one file takes milliseconds)."""
    from campaign.jobs.export import run

    options = dataclasses.replace(options, robot=robot_path(ws, options.robot),
                                  out=inside(ws, options.out, "out"))
    return answer(ws, lambda: run(options), options)


@router.post("/compensate", status_code=202, responses=QUEUED)
def compensate(options: CompensateOptions, request: Request,
               ws: Path = Depends(workspace)) -> JSONResponse:
    """The deflection along a path, the compensated joints and the robot program in ``out``;
    queued (202 with the job)."""

    options = dataclasses.replace(
        options, robot=robot_path(ws, options.robot), path=inside(ws, options.path, "path"),
        out=inside(ws, options.out, "out"),
        protocol=None if options.protocol is None else inside(ws, options.protocol,
                                                               "protocol"))
    return submit(request, ws, "compensate", options, job_tasks.compensate)


def _without(record: type, *names: str) -> type:
    """A dataclass of ``record``'s fields but ``names`` (same types and defaults): a request
    body that cannot carry what the server's operator chooses."""
    import typing

    hints = typing.get_type_hints(record)
    kept = [(f.name, hints[f.name], dataclasses.field(default=f.default)
             if f.default is not dataclasses.MISSING else dataclasses.field())
            for f in dataclasses.fields(record) if f.name not in names]
    made = dataclasses.make_dataclass(f"{record.__name__}Request", kept)
    made.__doc__ = f"{record.__doc__}\n\nWithout {', '.join(names)}: the server's choice."
    return made


#: the place job's options but the Dask scheduler: the server connects to the scheduler
#: its operator gave (``campaign gui --scheduler``), never to one a request names
PlaceRequest = _without(PlaceOptions, "scheduler")


@router.post("/place", status_code=202, responses=QUEUED)
def place(body: PlaceRequest, request: Request,
          ws: Path = Depends(workspace)) -> JSONResponse:
    """The placement search (options in the command line's units: mm, deg, ``A..B`` ranges);
    the options and the search's size are checked at once (400; at most
    :data:`MAX_EVALUATIONS` evaluations), then the search is queued (202 with the job,
    whose result is placement.json). ``workers`` 0 runs it in the server's process, else
    on a local Dask cluster as the command line, or on the operator's scheduler
    (``campaign gui --scheduler``)."""
    from campaign.use.place_run import check_search

    options = PlaceOptions(**{f.name: getattr(body, f.name)
                              for f in dataclasses.fields(body)},
                           scheduler=getattr(request.app.state, "scheduler", None))
    options = dataclasses.replace(options, robot=robot_path(ws, options.robot),
                                  path=inside(ws, options.path, "path"),
                                  out=inside(ws, options.out, "out"))
    refused = answer(ws, lambda: check_search(options, MAX_EVALUATIONS), options,
                     present=lambda size: None)
    if refused is not None:
        return refused
    return submit(request, ws, "place", options, job_tasks.place, (MAX_EVALUATIONS,))


@router.post("/robustness", status_code=202, responses=QUEUED)
def robustness(options: RobustnessOptions, request: Request,
               ws: Path = Depends(workspace)) -> JSONResponse:
    """The Monte-Carlo spread of k against the number of tests (noise overrides in SI);
    the options are checked at once as the command line checks them (400), then queued
    (202 with the job; at most :data:`MAX_CAMPAIGNS` simulated campaigns, trials x numbers
    of tests)."""
    from campaign.jobs.robustness import check

    refused = answer(ws, lambda: check(options), options, present=lambda counts: None)
    if refused is not None:
        return refused
    campaigns = options.trials * len(set(options.tests))
    if campaigns > MAX_CAMPAIGNS:
        return bound_error("trials", f"{options.trials} trials x {len(set(options.tests))} "
                           f"numbers of tests = {campaigns} simulated campaigns, above this "
                           f"server's limit of {MAX_CAMPAIGNS} per request")
    options = dataclasses.replace(
        options, robot=robot_path(ws, options.robot),
        out=None if options.out is None else inside(ws, options.out, "out"))
    return submit(request, ws, "robustness", options, job_tasks.robustness)


@router.post("/analyze", status_code=202, responses=QUEUED)
def analyze(options: AnalyzeOptions, request: Request,
            ws: Path = Depends(workspace)) -> JSONResponse:
    """Identify k from a run directory or a tests CSV (noise overrides in SI, fractions for
    the relative F/T noise); queued (202 with the job, whose result is results.json with
    analysis.json and the files)."""
    def opt(value, name):
        return None if value is None else inside(ws, value, name)

    options = dataclasses.replace(
        options, run_dir=opt(options.run_dir, "run_dir"),
        measurements=opt(options.measurements, "measurements"),
        robot=None if options.robot is None else robot_path(ws, options.robot),
        out=opt(options.out, "out"),
        # the ledger is the server operator's (campaign gui --db), never a request's: a
        # client must not make the server connect to a database of its choosing
        ledger=getattr(request.app.state, "ledger", None))
    return submit(request, ws, "analyze", options, job_tasks.analyze)


@router.post("/acquire", status_code=202, responses={**QUEUED, 403: {
    "model": Refusal, "description": "a real robot from a server started without "
    "--hardware"}, 409: {"model": Refusal, "description": "an acquisition is running on "
                         "this robot"}})
def acquire(options: AcquireJobOptions, request: Request,
            ws: Path = Depends(workspace)) -> JSONResponse:
    """Run, resume or dry-run a campaign; queued (202 with the job, whose result is the
    status and counts). Cancelling it takes the Ctrl-C path (motion stopped, load
    removed, ``aborted`` recorded: the run stays, resumable, as the command line's).

    Without ``out`` a new run goes to ``runs/run-<UTC time>`` in the workspace. The
    rule of every acquisition route (:mod:`campaign.web.acquire_rule`): a real robot
    only from a server started with ``--hardware`` (403) and with ``assume_yes`` (400),
    one acquisition per robot at a time (409). ``events_file`` must be a new file (the
    server writes there). A long campaign is better started from the Acquire view (its
    own process, which a closed page or a restarted server does not stop)."""
    from campaign.jobs.acquire import check, default_run_dir
    from campaign.web.acquire_rule import check_free, check_hardware

    refused = answer(ws, lambda: check(options), options, present=lambda _: None)
    if refused is not None:  # the command line's own line for the options themselves
        return refused

    def opt(value, name):
        return None if value is None else inside(ws, value, name)

    out = options.out
    if out is None and options.resume is None and options.plan is not None \
            and not options.dry_run:
        out = default_run_dir()
    options = dataclasses.replace(
        options, plan=opt(options.plan, "plan"), out=opt(out, "out"),
        resume=opt(options.resume, "resume"), events_file=opt(options.events_file,
                                                              "events_file"))
    check_hardware(getattr(request.app.state, "hardware", False), options.fake,
                   options.assume_yes, options.dry_run)
    if options.events_file is not None and os.path.lexists(options.events_file):
        return bound_error("events_file", "an existing file, refused: the server writes "
                           "the progress there, so give the name of a new file")
    claim = None
    source = options.resume or options.plan
    if not options.dry_run and source is not None:
        claim = check_free(ws, source)  # 409 now; the job's process holds it while it runs
    return submit(request, ws, "acquire", options, job_tasks.acquire,
                  () if claim is None else claim, cleanup=False)


# the queue's own routes: a job's state, its events, its cancellation
router.include_router(queue_router)
