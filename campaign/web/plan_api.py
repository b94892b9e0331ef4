"""``/api/plan``: the Plan view's server side (a protocol form, the plan job on it).

The form edits a few keys of a protocol (a shipped one from ``protocols/`` or a
``.toml`` of the workspace), named by their dotted keys (``campaign.tests``,
``instruments.pose.noise.translation_um``). Values arrive as the user typed them and
are written as numbers where they read as numbers; anything else is written as typed,
so the protocol reader itself refuses it with the command line's own one-line message
(``FILE:LINE: KEY: why``), which the answer names the field of. The protocol is saved
as ``protocols/NAME.toml`` in the workspace and planned into ``plans/NAME``.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from fastapi import APIRouter, Query, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

router = APIRouter(prefix="/api/plan", tags=["plan"])

SHIPPED = Path(__file__).resolve().parents[1] / "protocols"  # package data
#: the keys of the form: dotted key, label with its unit (the protocol's own units)
FIELDS: tuple[tuple[str, str], ...] = (
    ("campaign.name", "campaign name"),
    ("campaign.robot", "robot (built-in name or robot file)"),
    ("campaign.tests", "number of tests (poses)"),
    ("campaign.repeats", "repeats per test"),
    ("tool.xyz_mm", "tool point x,y,z in the flange frame (mm)"),
    ("tool.rpy_deg", "tool frame roll,pitch,yaw (deg)"),
    ("tool.mass_kg", "tool mass (kg)"),
    ("instruments.force_torque.mount_xyz_mm", "F/T sensor origin in the tool frame (mm)"),
    ("loads.selection", "load selection (per-pose or all)"),
    ("load_cases.0.name", "first load case: name"),
    ("load_cases.0.force_N", "first load case: force fx,fy,fz (N)"),
    ("load_cases.0.moment_N_m", "first load case: moment mx,my,mz (N m)"),
    ("instruments.force_torque.noise.force_N", "F/T force noise (N)"),
    ("instruments.force_torque.noise.torque_N_m", "F/T moment noise (N m)"),
    ("instruments.pose.noise.translation_um", "tracker translation noise (\u00b5m)"),
    ("instruments.pose.noise.rotation_urad", "tracker rotation noise (\u00b5rad)"),
    ("thresholds.min_inv_kappa_F", "minimum 1/kappa_F"),
    ("thresholds.max_v_p", "maximum v_p"),
    ("thresholds.max_v_r_deg", "maximum v_r (deg)"),
    ("sampling.use_robot_zones", "sample the robot's zones (true/false)"),
    ("safety.joint_margin_deg", "joint margin (deg)"),
    ("safety.max_joint_speed_deg_s", "maximum joint speed (deg/s)"),
    ("safety.max_joint_acceleration_deg_s2", "maximum joint acceleration (deg/s\u00b2)"),
    ("safety.approach_offset_mm", "approach offset (mm)"),
)
NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


class PlanRequest(BaseModel):
    """source: a shipped protocol's file name or a workspace .toml path; values: dotted
    key -> the text typed; name: of the saved protocol and plan directory."""

    source: str = Field("kr240-2.toml", max_length=300)
    values: dict[str, str] = Field(default_factory=dict)
    name: str = Field("plan-gui", max_length=64)
    strategy: str = Field("worst-joint", max_length=40)
    seed: int = Field(0, ge=0, le=2**31)
    candidates: int = Field(2000, ge=10, le=100_000)


def _error(text: str, field: str | None = None, status: int = 400) -> JSONResponse:
    return JSONResponse({"detail": text, "field": field}, status_code=status)


def _source(ws: Path, source: str) -> Path:
    from campaign.web.security import inside_workspace

    if "/" not in source and (SHIPPED / source).is_file():
        return SHIPPED / source
    return inside_workspace(ws, source, "source")


def _get(doc, key: str):
    for part in key.split("."):
        if isinstance(doc, list):
            doc = doc[int(part)] if part.isdigit() and int(part) < len(doc) else None
        elif isinstance(doc, dict):
            doc = doc.get(part)
        else:
            return None
    return doc


def _set(doc, key: str, value) -> bool:
    parts = key.split(".")
    for part in parts[:-1]:
        if isinstance(doc, list):
            if not (part.isdigit() and int(part) < len(doc)):
                return False
            doc = doc[int(part)]
        else:
            doc = doc.setdefault(part, {})
    if not isinstance(doc, dict):
        return False
    doc[parts[-1]] = value
    return True


def _text(value) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return ",".join(_text(v) for v in value)
    return str(value)


def _parse(text: str, like):
    """``text`` as the type of ``like`` where it reads so; else the text (refused later
    by the protocol reader with its own message)."""
    t = text.strip()
    try:
        if isinstance(like, bool):
            return {"true": True, "false": False}.get(t.lower(), t)
        if isinstance(like, list):
            return [float(v) for v in t.split(",")]
        if isinstance(like, int):
            return int(t)
        if isinstance(like, float):
            return float(t)
    except ValueError:
        return t
    if like is None:  # a key the protocol does not have: a number, a list, else text
        for parse in (int, float, lambda v: [float(x) for x in v.split(",")]):
            try:
                return parse(t)
            except ValueError:
                pass
    return t


@router.get("/protocols")
def protocols(request: Request) -> dict:
    """The shipped protocols (file names) and the workspace's ``protocols/*.toml``."""
    ws = Path(request.app.state.workspace)
    mine = sorted(str(p.relative_to(ws)) for p in (ws / "protocols").glob("*.toml")
                  if p.is_file() and not p.is_symlink()) if (ws / "protocols").is_dir() else []
    return {"shipped": sorted(p.name for p in SHIPPED.glob("*.toml")), "workspace": mine,
            "strategies": _strategies()}


def _strategies() -> list[str]:
    from campaign.jobs.choices import Strategy

    return [s.value for s in Strategy]


@router.get("/form")
def form(request: Request, source: str = Query("kr240-2.toml", max_length=300)):
    """The form's keys, labels and values in ``source`` (the protocol's own units)."""
    try:
        path = _source(Path(request.app.state.workspace), source)
        doc = tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        return _error(f"source: {source}: {err}", "source")
    return {"source": source, "fields": [
        {"key": k, "label": label, "value": _text(_get(doc, k))} for k, label in FIELDS]}


def _field_of(message: str) -> str | None:
    """The form's key a protocol or job message names (``FILE:LINE: KEY: why``)."""
    known = [k for k, _ in FIELDS] + ["strategy", "seed", "candidates", "name"]
    hits = [k for k in known if re.search(rf"(^|[\s:]){re.escape(k)}:", message)]
    return max(hits, key=len) if hits else None


@router.post("/run")
def run_plan(request: Request, body: PlanRequest):
    """Save the edited protocol as ``protocols/NAME.toml`` and plan it into ``plans/NAME``
    (replacing a plan of that name); the answer is summary.json with the plan's rows."""
    import tomli_w

    from analysis.errors import InputError
    from campaign.jobs.plan import PlanOptions, run

    ws = Path(request.app.state.workspace)
    if not NAME.match(body.name):
        return _error("name: letters, digits, '.', '_' and '-' only", "name")
    try:
        src = _source(ws, body.source)
        doc = tomllib.loads(src.read_text())
    except InputError as err:
        return _error(str(err), "source")
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError) as err:
        return _error(f"source: {body.source}: {err}", "source")
    keys = {k for k, _ in FIELDS}
    for key, text in body.values.items():
        if key not in keys:
            return _error(f"{key}: not a key of the form", None)
        if not _set(doc, key, _parse(text, _get(doc, key))):
            return _error(f"{key}: the protocol has no such table", key)
    from campaign.jobs.choices import Strategy

    try:
        strategy = Strategy(body.strategy)
    except ValueError:
        return _error(f"strategy: {body.strategy!r} is not one of {', '.join(_strategies())}",
                      "strategy")
    (ws / "protocols").mkdir(exist_ok=True)
    (ws / "plans").mkdir(exist_ok=True)
    proto = ws / "protocols" / f"{body.name}.toml"
    out = ws / "plans" / body.name
    for p in (proto, out):
        if p.is_symlink():
            return _error(f"{p.relative_to(ws)}: a symbolic link; refused", "name")
    proto.write_text(f"# edited in campaign gui from {body.source}\n" + tomli_w.dumps(doc))
    try:
        result = run(PlanOptions(protocol=proto, out=out, strategy=strategy, seed=body.seed,
                                 candidates=body.candidates, force=True))
    except InputError as err:
        text = str(err).replace(f"{ws}/", "")
        return _error(text, _field_of(text))
    except Exception as err:
        if type(err).__name__ == "EquilibriumError":
            return _error(f"nonlinear equilibrium: {err}; reduce the wrench", None)
        raise
    import pandas as pd

    from campaign.jobs.choices import json_ready

    rows = pd.read_csv(out / "plan.csv").to_dict(orient="records")
    return JSONResponse(json_ready({
        "summary": result.summary, "rows": rows, "protocol": str(proto.relative_to(ws)),
        "out": str(out.relative_to(ws)),
        "files": sorted(str(p.relative_to(ws)) for p in out.iterdir() if p.is_file())}))
