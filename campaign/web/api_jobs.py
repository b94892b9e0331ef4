"""``/api/jobs``: one POST endpoint per job of :mod:`campaign.jobs`.

Request bodies are the jobs' options records themselves (FastAPI reads the
dataclasses), so the units are the records' SI units (radians, N, N m, m),
not the degrees and millimetres the command line takes at its edge; a tool
point is given as the protocol's ``[tool]`` table gives it (mm, deg), and the
field names say so. Responses are the result records as JSON, the same
documents the command's ``--json`` prints (NaN and infinities as null).

Every path in a body is relative to the workspace (``request.app.state.workspace``):
an absolute path, a ``..`` part, or a symbolic link that leads out of it is
refused with 400 and one line. The jobs get absolute paths, so the files they
write name workspace files by absolute path where the command line would write
the path as typed; the JSON answers give them relative to the workspace.
Bad input gets 400 (or 422 from the body's
schema) with the same one-line message as the command line; a refused write
(disk full, permissions) is 409 with the file named.
"""

from __future__ import annotations

import dataclasses
import errno
from collections.abc import Callable
from pathlib import Path, PurePosixPath
from typing import Any

from fastapi import APIRouter, Depends, HTTPException, Request
from fastapi.responses import JSONResponse

from analysis.errors import InputError
from campaign.cli.common import json_ready
from campaign.jobs.acquire import AcquireJobOptions
from campaign.jobs.analyze import AnalyzeOptions
from campaign.jobs.compare import CompareOptions
from campaign.jobs.compensate import CompensateOptions
from campaign.jobs.maps import MapsOptions
from campaign.jobs.place import PlaceOptions
from campaign.jobs.plan import PlanOptions
from campaign.jobs.robots import RobotsOptions
from campaign.jobs.robustness import RobustnessOptions
from campaign.jobs.stiffness import StiffnessOptions

router = APIRouter(prefix="/api/jobs", tags=["jobs"])


def workspace(request: Request) -> Path:
    """The workspace directory of the application (``app.state.workspace``), resolved."""
    ws = getattr(request.app.state, "workspace", None)
    if ws is None:
        raise HTTPException(500, "the application has no workspace directory")
    return Path(ws).resolve()


def inside(ws: Path, rel: str | Path, field: str) -> Path:
    """``rel`` (relative to the workspace) as an absolute path inside it; refuse the rest.

    Refused with 400: an absolute path, a ``..`` part, and a path whose existing
    part resolves (through symbolic links) outside the workspace.
    """
    text = str(rel)
    if "\x00" in text:
        raise HTTPException(400, f"{field}: a path cannot hold a NUL character")
    parts = PurePosixPath(text.replace("\\", "/")).parts
    if not text or text.startswith(("/", "\\")) or (parts and ":" in parts[0]):
        raise HTTPException(400, f"{field}: {text!r} is not a path relative to the workspace")
    if ".." in parts:
        raise HTTPException(400, f"{field}: {text!r} has a '..' part; paths stay inside "
                                 "the workspace")
    if any(len(part.encode()) > 255 for part in parts):
        raise HTTPException(400, f"{field}: a name in the path is longer than 255 bytes")
    path = ws.joinpath(*parts)
    try:
        resolved = path.resolve()
    except (OSError, RuntimeError) as err:  # a name too long, a symbolic link loop
        raise HTTPException(400, f"{field}: {text!r}: {getattr(err, 'strerror', None) or err}"
                            ) from None
    if not resolved.is_relative_to(ws):
        raise HTTPException(400, f"{field}: {text!r} leads out of the workspace "
                                 "(symbolic link)")
    return path


def _relative(ws: Path, doc: Any) -> Any:
    """``doc`` with the workspace's absolute paths written relative to it."""
    if isinstance(doc, dict):
        return {k: _relative(ws, v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_relative(ws, v) for v in doc]
    if isinstance(doc, str):
        return doc.replace(f"{ws}/", "")
    return doc


def call(ws: Path | None, job: Callable[[], Any]) -> JSONResponse:
    """Run ``job()``; its result record as JSON, or bad input as 400 with its one line."""
    try:
        result = job()
    except InputError as err:
        text = str(err) if ws is None else str(err).replace(f"{ws}/", "")
        raise HTTPException(400, text) from None
    except OSError as err:
        where = f"{err.filename}: " if err.filename else ""
        text = f"{where}{err.strerror or err}"
        if ws is not None:
            text = text.replace(f"{ws}/", "")
        # a name the file system cannot take is bad input; a refused write is a conflict
        status = 400 if err.errno in (errno.ENAMETOOLONG, errno.EINVAL) else 409
        raise HTTPException(status, text) from None
    except Exception as err:
        if type(err).__name__ == "EquilibriumError":
            raise HTTPException(400, f"nonlinear equilibrium: {err}; reduce the wrench or "
                                     "check the joint stiffness") from None
        raise
    doc = json_ready(result.to_json())
    return JSONResponse(doc if ws is None else _relative(ws, doc))


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
    return call(ws, lambda: run(options))


@router.post("/stiffness")
def stiffness(options: StiffnessOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """J, K_C, K_X and the deflection at one pose (q in rad, k in N m/rad, wrench N, N m)."""
    from campaign.jobs.stiffness import run

    options = dataclasses.replace(options, robot=robot_path(ws, options.robot))
    return call(ws, lambda: run(options))


@router.post("/plan")
def plan(options: PlanOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """Plan the tests of a protocol file; writes the plan directory ``out`` (workspace paths)."""
    from campaign.jobs.plan import run

    options = dataclasses.replace(options, protocol=inside(ws, options.protocol, "protocol"),
                                  out=inside(ws, options.out, "out"))
    return call(ws, lambda: run(options))


@router.post("/maps")
def maps(options: MapsOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """The paper's Figs. 3 and 5 maps into ``out`` (grid step and fixed joints in rad)."""
    from campaign.jobs.maps import run

    options = dataclasses.replace(options, robot=robot_path(ws, options.robot),
                                  out=inside(ws, options.out, "out"))
    return call(ws, lambda: run(options))


@router.post("/compare")
def compare(options: CompareOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """k_B - k_A per joint with its interval, z score and verdict (campaign paths a and b)."""
    from campaign.jobs.compare import run

    options = dataclasses.replace(
        options, a=inside(ws, options.a, "a"), b=inside(ws, options.b, "b"),
        plot=None if options.plot is None else inside(ws, options.plot, "plot"),
        report=None if options.report is None else inside(ws, options.report, "report"))
    return call(ws, lambda: run(options))


@router.post("/compensate")
def compensate(options: CompensateOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """The deflection along a path, the compensated joints and the robot program in ``out``."""
    from campaign.jobs.compensate import run

    options = dataclasses.replace(
        options, robot=robot_path(ws, options.robot), path=inside(ws, options.path, "path"),
        out=inside(ws, options.out, "out"),
        protocol=None if options.protocol is None else inside(ws, options.protocol,
                                                               "protocol"))
    return call(ws, lambda: run(options))


@router.post("/place")
def place(options: PlaceOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """The placement search (options in the command line's units: mm, deg, ``A..B`` ranges);
    the answer is placement.json. ``workers`` 0 runs the search in the server's process."""
    from campaign.jobs.place import run

    options = dataclasses.replace(options, robot=robot_path(ws, options.robot),
                                  path=inside(ws, options.path, "path"),
                                  out=inside(ws, options.out, "out"))
    return call(ws, lambda: run(options))


@router.post("/robustness")
def robustness(options: RobustnessOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """The Monte-Carlo spread of k against the number of tests (noise overrides in SI)."""
    from campaign.jobs.robustness import run

    options = dataclasses.replace(
        options, robot=robot_path(ws, options.robot),
        out=None if options.out is None else inside(ws, options.out, "out"))
    return call(ws, lambda: run(options))


@router.post("/analyze")
def analyze(options: AnalyzeOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """Identify k from a run directory or a tests CSV (noise overrides in SI, fractions for
    the relative F/T noise); the answer is results.json with analysis.json and the files."""
    from campaign.jobs.analyze import run

    def opt(value, name):
        return None if value is None else inside(ws, value, name)

    options = dataclasses.replace(
        options, run_dir=opt(options.run_dir, "run_dir"),
        measurements=opt(options.measurements, "measurements"),
        robot=None if options.robot is None else robot_path(ws, options.robot),
        out=opt(options.out, "out"))
    return call(ws, lambda: run(options))


@router.post("/acquire")
def acquire(options: AcquireJobOptions, ws: Path = Depends(workspace)) -> JSONResponse:
    """Run, resume or dry-run a campaign and answer when it ends (status, counts).

    Without ``out`` a new run goes to ``runs/run-<UTC time>`` in the workspace. A real
    robot moves only with ``assume_yes`` (nobody can be asked here); a long campaign is
    better started as its own process (``python -m campaign.jobs.acquire``), which a
    closed page does not stop."""
    from campaign.jobs.acquire import default_run_dir, run

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
    return call(ws, lambda: run(options, say=lambda s: None))
