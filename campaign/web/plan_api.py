"""``/api/plan``: the Plan view's server side (the protocol form, the plan job on it).

The form holds every key of the protocol schema (:mod:`campaign.web.protocol_form`),
filled from a protocol (a shipped one from ``protocols/`` or a ``.toml`` of the
workspace). Values arrive as the user typed them, named by the key paths of the
command line's messages (``campaign.tests``, ``load_cases[1].force_N``); what does
not read as its field's kind is written as typed, so the protocol reader itself
refuses it with the command line's own one-line message (``FILE:LINE: KEY: why``),
which the answer names the field of. The protocol is saved as
``protocols/NAME.toml`` in the workspace and planned into ``plans/NAME``.
"""

from __future__ import annotations

import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Annotated

from fastapi import APIRouter, Query, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

from analysis.errors import InputError
from campaign.jobs.plan import PlanOptions
from campaign.web.job_submit import QUEUED, submit

router = APIRouter(prefix="/api/plan", tags=["plan"])

SHIPPED = Path(__file__).resolve().parents[1] / "protocols"  # package data
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class PlanRequest(BaseModel):
    """source: a shipped protocol's file name or a workspace .toml path; values: key ->
    the text typed (an empty text leaves the key out); complete: ``values`` is the whole
    form (else they change the source's values); name: of the saved protocol and plan
    directory; strategy, seed, candidates: the planner's (``campaign plan`` options);
    force: replace ``protocols/NAME.toml`` and ``plans/NAME`` when they exist (as the
    command line's ``--force``; without it an existing name is refused and nothing changes)."""

    source: str = Field("kr240-2.toml", max_length=300)
    values: dict[str, Annotated[str, Field(max_length=20_000)]] = Field(
        default_factory=dict, max_length=2000)
    complete: bool = False
    name: str = Field("plan-gui", max_length=64)
    strategy: str = Field("worst-joint", max_length=40)
    seed: int = Field(0, ge=0, le=2**31)
    candidates: int = Field(PlanOptions.candidates, ge=10, le=100_000)  # the CLI's default
    force: bool = False


def _error(text: str, field: str | None = None, status: int = 400,
           problems: list[dict] | None = None, options: dict | None = None) -> JSONResponse:
    """A refusal: its line, the field at fault, one problem per line, and ``options``: each
    command-line option the text names -> the request field (campaign.web.job_errors)."""
    return JSONResponse({"detail": text, "field": field,
                         "problems": problems or [{"field": field, "detail": text}],
                         "options": options or {}}, status_code=status)


def _source(ws: Path, source: str) -> Path:
    from campaign.web.security import inside_workspace

    try:
        shipped = "/" not in source and (SHIPPED / source).is_file()
    except (OSError, ValueError):  # a name too long, a NUL byte: no shipped protocol
        shipped = False
    return SHIPPED / source if shipped else inside_workspace(ws, source, "source")


@router.get("/protocols")
def protocols(request: Request) -> dict:
    """The shipped protocols (file names) and the workspace's ``protocols/*.toml``."""
    ws = Path(request.app.state.workspace)
    found = [*(ws / "protocols").glob("*.toml"), *ws.glob("*/protocol.toml"),
             *ws.glob("*/*/protocol.toml")]
    mine = sorted({str(p.relative_to(ws)) for p in found if p.is_file()
                   and not p.is_symlink() and not p.parent.is_symlink()})
    return {"shipped": sorted(p.name for p in SHIPPED.glob("*.toml")), "workspace": mine,
            "strategies": _strategies()}


def _strategies() -> list[str]:
    from campaign.jobs.choices import Strategy

    return [s.value for s in Strategy]


def _document(ws: Path, source: str) -> dict:
    """The TOML document of ``source`` (InputError naming it when unreadable)."""
    from analysis.errors import InputError
    from analysis.file_errors import decode_utf8

    path = _source(ws, source)
    try:
        text = decode_utf8(path.read_bytes(), source, "protocol file")
        return tomllib.loads(text)
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", where=source) from None
    except (tomllib.TOMLDecodeError, ValueError) as err:  # ValueError: a 4300-digit int
        raise InputError(f"not TOML: {err}", where=source) from None


@router.get("/form")
def form(request: Request, source: str = Query("kr240-2.toml", max_length=300)):
    """Every field of the protocol form (key, kind, unit, default) and ``source``'s values
    (text, the protocol's own units); ``values`` holds only keys ``source`` sets."""
    from analysis.errors import InputError
    from campaign.web.protocol_form import FormError, form_fields, form_values

    try:
        values = form_values(_document(Path(request.app.state.workspace), source))
    except InputError as err:
        return _error(str(err), "source")
    except FormError as err:
        return _error(f"source: {source}: {err}", "source")
    return {"source": source, "fields": [_suggest(f.to_dict(), request) for f in form_fields()],
            "values": values}


def _shipped_addresses() -> list[str]:
    """The instrument addresses of the shipped protocols (examples of each scheme)."""
    out = set()
    for path in SHIPPED.glob("*.toml"):
        try:
            doc = tomllib.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        for spec in (doc.get("instruments") or {}).values():
            if isinstance(spec, dict) and isinstance(spec.get("address"), str):
                out.add(spec["address"])
    return sorted(out)


def _suggest(field: dict, request: Request) -> dict:
    """campaign.robot: the pickers' robots, files named relative to ``protocols/`` (where
    the form saves the protocol; a robot file is read relative to its protocol);
    addresses: the shipped protocols' (one per driver and scheme)."""
    if field["key"] == "instruments.*.address":
        field["suggestions"] = _shipped_addresses()
    if field["key"] == "campaign.robot":
        from campaign.web.robots_api import robot_choices

        field["suggestions"] = [c.value if c.kind == "builtin" else f"../{c.value}"
                                for c in robot_choices(request.app.state.workspace)]
    return field


def _robot_outside(ws: Path, values: dict[str, str]) -> JSONResponse | None:
    """The refusal of a ``campaign.robot`` file that is not a workspace file, or None.

    The saved protocol is ``protocols/NAME.toml`` and names its robot file relative to
    ``protocols/``: that path, seen from the workspace, must pass the web's path rule
    (:func:`campaign.web.security.inside_workspace`) before the protocol reader opens it,
    so that neither its keys nor its existence leak from outside the workspace."""
    from analysis.errors import InputError
    from analysis.model.robot_spec import is_robot_file, split_urdf_spec
    from campaign.web.security import inside_workspace

    text = values.get("campaign.robot", "").strip().strip("\"'")
    if not is_robot_file(text):
        return None  # a built-in name
    parts = list(PurePosixPath(split_urdf_spec(text)[0].replace("\\", "/")).parts)
    up = 0 if not parts or parts[0] != ".." else 1  # protocols/../ is the workspace
    rel = "/".join(parts[up:] if up else ["protocols", *parts])
    checked = rel if parts and not PurePosixPath(parts[0]).is_absolute() else text
    try:
        inside_workspace(ws, checked, "campaign.robot")
    except InputError as err:  # the path as typed, not as seen from the workspace
        return _error(f"{str(err).replace(repr(checked), repr(text))} (a robot file is "
                      "read relative to protocols/ of the workspace)", "campaign.robot")
    return None


def _problems(text: str, keys: list[str]) -> list[dict]:
    """One entry per line of a protocol or job message, with the form key it names."""
    from campaign.web.protocol_form import field_of

    known = keys + ["strategy", "seed", "candidates", "name", "force"]
    return [{"field": field_of(line, known), "detail": line}
            for line in text.splitlines() if line.strip()]


def _save(ws: Path, body: PlanRequest) -> tuple[Path, list[str], bytes | None] | JSONResponse:
    """Write the form as ``protocols/NAME.toml``: (its path, the form's keys, the file's
    previous bytes or None when it is new), or the refusal naming the field."""
    import tomli_w

    from analysis.errors import InputError
    from campaign.web.protocol_form import FormError, build_document, field_keys, form_values

    if not NAME.match(body.name):
        return _error("name: letters, digits, '.', '_' and '-' only", "name")
    try:
        values = {} if body.complete else form_values(_document(ws, body.source))
    except InputError as err:
        return _error(str(err), "source")
    except FormError as err:
        return _error(f"source: {body.source}: {err}", "source")
    values.update(body.values)
    keys = field_keys(values)
    try:
        doc = build_document(values)
    except FormError as err:
        return _error(str(err), err.key if err.key in keys else None)
    outside = _robot_outside(ws, values)
    if outside is not None:
        return outside
    for sub in ("protocols", "plans"):
        if (ws / sub).is_symlink():
            return _error(f"{sub}: a symbolic link; refused", "name")
        (ws / sub).mkdir(exist_ok=True)
    proto = ws / "protocols" / f"{body.name}.toml"
    for p in (proto, ws / "plans" / body.name):
        if p.is_symlink():
            return _error(f"{p.relative_to(ws)}: a symbolic link; refused", "name")
    source = body.source.replace("\n", " ").splitlines()[0] if body.source else ""
    previous = proto.read_bytes() if proto.is_file() else None
    proto.write_text(f"# edited in campaign gui from {source}\n" + tomli_w.dumps(doc))
    return proto, keys, previous


def _restore(proto: Path, previous: bytes | None) -> None:
    """Put back the protocol file a refused form replaced (or remove the new one): a
    refused save leaves no unreadable protocol, nor a good one overwritten."""
    if previous is None:
        proto.unlink(missing_ok=True)
    else:
        proto.write_bytes(previous)


def _refusal(ws: Path, err: Exception, keys: list[str]) -> JSONResponse:
    from campaign.jobs.plan import PlanOptions
    from campaign.web.job_errors import OPTION, fields_of, option_field

    text = str(err).replace(f"{ws}/", "")
    problems = _problems(text, keys)
    names = fields_of(PlanOptions)
    named = {opt: name for opt in dict.fromkeys(OPTION.findall(text))
             if (name := option_field(opt, names)) is not None}
    return _error(text, problems[0]["field"] if problems else None, problems=problems,
                  options=named)


def _copy_warnings(proto: Path, out: Path) -> list[str]:
    """What the plan directory's protocol copy will not find (the plan writer copies a
    relative robot file beside it, :mod:`campaign.protocol_copy`; this says if it did not)."""
    from analysis.model.robot_spec import is_robot_file, split_urdf_spec
    from campaign.protocol import load_protocol

    robot = load_protocol(out / f"protocol{proto.suffix.lower()}").campaign.robot
    if not is_robot_file(robot) or Path(split_urdf_spec(robot)[0]).is_absolute():
        return []
    name = split_urdf_spec(robot)[0]
    if (out / name).exists():
        return []
    return [f"campaign.robot = {robot!r} is read relative to the protocol file: the plan's "
            f"copy {out.name}/protocol.toml names {out.name}/{name}, which does not exist, "
            "so acquiring or analysing from this plan directory will not find the robot; "
            "give its absolute path, or copy the robot file there"]


def _save_checked(ws: Path, body: PlanRequest,
                  plan: bool = False) -> tuple[Path, list[str]] | JSONResponse:
    """Write the form as its protocol file and read it back with the protocol reader: the
    (path, field keys), or the reader's refusal with the former file put back. A protocol
    (and with ``plan``, a plan directory) of that name already there is refused unless
    ``body.force``, once the form is known to be good, the former file put back."""
    from analysis.errors import InputError
    from campaign.protocol import load_protocol

    saved = _save(ws, body)
    if isinstance(saved, JSONResponse):
        return saved
    proto, keys, previous = saved
    try:
        load_protocol(proto)
    except InputError as err:
        refusal = _refusal(ws, err, keys)
        _restore(proto, previous)
        return refusal
    taken = [p for p in (proto if previous is not None else None,
                         ws / "plans" / body.name if plan else None)
             if p is not None and os.path.lexists(p)]
    if taken and not body.force:
        _restore(proto, previous)
        names = " and ".join(str(p.relative_to(ws)) for p in taken)
        return _error(f"name: {names} already exist{'s' if len(taken) == 1 else ''}: add "
                      "--force to replace, or choose another name", "name",
                      options={"--force": "force"})
    return proto, keys


@router.post("/save")
def save_protocol(request: Request, body: PlanRequest):
    """Save the form as ``protocols/NAME.toml`` and read it back with the protocol reader
    (``load_protocol``: schema, units, safety limits, drivers and addresses); the
    answer: the saved path, or the reader's message per field."""
    ws = Path(request.app.state.workspace)
    saved = _save_checked(ws, body)
    if isinstance(saved, JSONResponse):
        return saved
    proto, _ = saved
    return {"protocol": str(proto.relative_to(ws))}


@router.post("/run", status_code=202, responses=QUEUED)
def run_plan(request: Request, body: PlanRequest):
    """Save the form as ``protocols/NAME.toml`` (read back at once: a refusal is 400 with
    its message per field) and plan it into ``plans/NAME`` (replacing them only with
    ``force``) as a queued job: 202 with the job, whose result is summary.json, the plan's
    rows and the zone map's data, and whose refusal carries ``problems``, one per line
    with the form key it names."""
    from campaign.jobs.choices import Strategy
    from campaign.web import job_tasks

    ws = Path(request.app.state.workspace)
    try:
        strategy = Strategy(body.strategy)
    except ValueError:
        return _error(f"strategy: {body.strategy!r} is not one of {', '.join(_strategies())}",
                      "strategy")
    saved = _save_checked(ws, body, plan=True)
    if isinstance(saved, JSONResponse):
        return saved
    proto, keys = saved
    options = PlanOptions(protocol=proto, out=ws / "plans" / body.name, strategy=strategy,
                          seed=body.seed, candidates=body.candidates, force=True,
                          map_points=True)
    return submit(request, ws, "plan", options, job_tasks.plan_for_the_form,
                  extra=(tuple(keys),))


@dataclass(frozen=True)
class PlanShown:
    """What the Plan view shows of a plan: summary.json's document, plan.csv's rows, the
    zone map's data, the protocol copy's warnings, and the paths (absolute: the queue
    writes them relative to the workspace)."""

    summary: dict
    rows: list
    map: dict | None
    warnings: list
    protocol: Path
    out: Path
    files: list

    def to_json(self) -> dict:
        return {"summary": self.summary, "rows": self.rows, "map": self.map,
                "warnings": self.warnings, "protocol": str(self.protocol),
                "out": str(self.out), "files": [str(f) for f in self.files]}


def planned(result, protocol: Path) -> PlanShown:
    """The plan job's ``result`` (planned from ``protocol``) as the Plan view shows it."""
    import pandas as pd

    out = Path(result.plan_file).parent
    rows = pd.read_csv(out / "plan.csv").to_dict(orient="records")
    return PlanShown(result.summary, rows, result.map, _copy_warnings(protocol, out),
                     protocol, out, sorted(p for p in out.iterdir() if p.is_file()))


class FormRefusal(InputError):
    """A refusal of the plan job with ``problems``: each line of its message with the form
    key it names (``[{"field", "detail"}]``), for the page to show beside the field."""

    def __init__(self, message: str, problems: list[dict], where: str | None = None):
        self.problems = problems
        self.message = message
        super().__init__(message)
        self.where = where

    def __reduce__(self):
        return (_form_refusal, (self.message, self.problems, self.where))


def _form_refusal(message: str, problems: list[dict], where: str | None) -> FormRefusal:
    return FormRefusal(message, problems, where)


def form_refusal(err: InputError, keys: list[str]) -> FormRefusal:
    """The plan job's refusal ``err`` with its lines mapped to the form's ``keys``."""
    return FormRefusal(str(err), _problems(str(err), list(keys)), err.where)
