"""``/api/robots``: the robots the GUI's pickers offer (Sensitivity, Plan, Use), URDF uploads.

A picker's value is one string, the robot text of the command line
(:mod:`analysis.model.robot_spec`): a built-in name, a robot file or identified
``model.toml`` of the workspace, or a workspace URDF with its tool frame,
``robots/arm.urdf#tool0``. :func:`resolve_robot` turns such a value into what a job
loads (a file inside the workspace, else refused); every face that takes a picker's
value calls it. A URDF is listed once per frame that ends a chain of six revolute
joints. Uploads are size-limited, read by the command line's URDF reader
(:func:`analysis.model.robot_files.load_urdf`), its message shown as it says it, and
saved as ``robots/NAME.urdf``. The walk skips hidden directories, follows no symbolic
link and stops after :data:`MAX_FILES` files.
"""

from __future__ import annotations

import os
import re
import tomllib
from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, ConfigDict, Field

router = APIRouter(prefix="/api/robots", tags=["robots"])

#: largest URDF accepted by an upload (bytes of UTF-8 text)
MAX_URDF_BYTES = 1_000_000
#: files looked at, at most
MAX_FILES = 5000
#: where uploads are saved, inside the workspace
UPLOAD_DIR = "robots"
FILE_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,80}\.urdf$")
#: joints of the robots the jobs handle
JOINTS = 6


def resolve_robot(workspace: Path, spec: str, where: str = "robot") -> str:
    """What a job loads for a picker's value: a built-in name as given (an unknown one is
    refused by the job, naming ``where``); a file as its absolute path inside the
    workspace, with ``#FRAME`` kept (InputError for ``..``, absolute paths, links)."""
    from analysis.model.robot_spec import is_robot_file, split_urdf_spec
    from campaign.web.security import inside_workspace

    text = spec.strip()
    if not is_robot_file(text):
        return text
    path, frame = split_urdf_spec(text)
    resolved = str(inside_workspace(Path(workspace), path, where))
    return resolved + (f"#{frame}" if frame else "")


def _walk(ws: Path):
    seen = 0
    for root, dirs, files in os.walk(ws, followlinks=False):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(f for f in files if not f.startswith(".")):  # .upload-*: partial
            seen += 1
            if seen > MAX_FILES:
                return
            path = Path(root) / name
            if not path.is_symlink():
                yield path


def _is_robot_toml(path: Path) -> bool:
    """A robot file or an identified model: ``joints`` tables and no ``[campaign]``."""
    try:
        if path.stat().st_size > 2_000_000:
            return False
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return False
    return isinstance(doc.get("joints"), list) and "campaign" not in doc


def tip_frames(path: Path) -> list[str]:
    """Frames of a URDF that end a chain of :data:`JOINTS` revolute joints (tool0 and
    flange first); [] when pinocchio cannot read it."""
    import pinocchio as pin

    try:
        model = pin.buildModelFromUrdf(str(path))
    except (RuntimeError, ValueError):
        return []
    names = []
    for frame in model.frames:
        support = model.supports[frame.parentJoint]
        if len(support) - 1 == JOINTS and frame.name not in names and \
                frame.type in (pin.FrameType.BODY, pin.FrameType.OP_FRAME):
            names.append(frame.name)
    preferred = [n for n in ("tool0", "flange") if n in names]
    return preferred + [n for n in names if n not in preferred]


class RobotChoice(BaseModel):
    """value: the robot text to give a job (workspace-relative); kind: builtin, file or
    urdf; label: what the picker shows."""

    value: str
    label: str
    kind: str


class RobotChoices(BaseModel):
    robots: list[RobotChoice]
    max_upload_bytes: int


def robot_choices(workspace: Path) -> list[RobotChoice]:
    """Built-in robots, the workspace's robot files and models, its URDFs (one per tip)."""
    from analysis.model.robots import builtin_names

    ws = Path(workspace)
    out = [RobotChoice(value=n, label=f"{n} (built-in)", kind="builtin")
           for n in builtin_names()]
    for path in _walk(ws):
        rel = path.relative_to(ws).as_posix()
        suffix = path.suffix.lower()
        if suffix == ".toml" and path.name != "protocol.toml" and _is_robot_toml(path):
            kind = "identified model" if path.name == "model.toml" else "robot file"
            out.append(RobotChoice(value=rel, label=f"{rel} ({kind})", kind="file"))
        elif suffix == ".urdf" and path.stat().st_size <= MAX_URDF_BYTES:
            for tip in tip_frames(path):
                out.append(RobotChoice(value=f"{rel}#{tip}", label=f"{rel}, tool frame {tip} "
                                       "(URDF)", kind="urdf"))
    return out


@router.get("", response_model=RobotChoices)
def robots(request: Request) -> RobotChoices:
    """The robots a picker offers (values relative to the workspace)."""
    return RobotChoices(robots=robot_choices(request.app.state.workspace),
                        max_upload_bytes=MAX_URDF_BYTES)


class UrdfUpload(BaseModel):
    """name: the file name (``arm.urdf``), saved as ``robots/NAME``; text: the URDF;
    tip: its tool frame (None: the first frame ending a six-joint chain); replace: an
    existing ``robots/NAME``."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(max_length=90)
    # a cap on what is parsed at all; the size limit itself is the handler's, whose
    # message names the file (a schema error would name only body.text)
    text: str = Field(max_length=4 * MAX_URDF_BYTES)
    tip: str | None = Field(None, max_length=200)
    replace: bool = False


def _refused(text: str, field: str = "urdf") -> JSONResponse:
    return JSONResponse({"detail": text, "field": field}, status_code=400)


@router.post("/urdf")
def upload_urdf(request: Request, body: UrdfUpload):
    """Read the URDF with the command line's reader and save it as ``robots/NAME``; the
    answer: the picker's choices of it (one per tool frame)."""
    import tempfile

    from analysis.errors import InputError
    from analysis.model.robots import load_robot

    ws = Path(request.app.state.workspace)
    if not FILE_NAME.match(body.name):
        return _refused("name: letters, digits, '.', '_' and '-', ending in .urdf", "name")
    data = body.text.encode("utf-8")
    if len(data) > MAX_URDF_BYTES:
        return _refused(f"{body.name}: {len(data)} bytes; at most {MAX_URDF_BYTES} bytes")
    folder = ws / UPLOAD_DIR
    if folder.is_symlink() or (folder / body.name).is_symlink():
        return _refused(f"{UPLOAD_DIR}/{body.name}: a symbolic link; refused", "name")
    target = folder / body.name
    if target.exists() and not body.replace:
        return _refused(f"{UPLOAD_DIR}/{body.name} exists: tick replace, or rename", "name")
    folder.mkdir(exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".upload-", suffix=".urdf", dir=folder)
    shown = f"{UPLOAD_DIR}/{body.name}"
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        tips = tip_frames(Path(tmp))
        tip = body.tip or (tips[0] if tips else None)
        if tip is None:
            # the reader's own message for a file it cannot read, else: no six-joint chain
            load_robot(tmp, tip="tool0", where="tip")
            raise InputError(f"no frame ends a chain of {JOINTS} revolute joints: give "
                             "the tool frame (tip)", where=shown)
        robot = load_robot(f"{tmp}#{tip}", where="tip")
        if robot.n != JOINTS:
            raise InputError(f"expected a six-joint robot, got {robot.n} joints up to {tip!r}",
                             where="tip")
        os.replace(tmp, target)
    except InputError as err:
        Path(tmp).unlink(missing_ok=True)
        text = str(err).replace(tmp, shown)
        return _refused(text, "tip" if text.startswith(("tip:", "--tip:")) else "urdf")
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    frames = [tip] + [t for t in tips if t != tip]
    return {"saved": shown, "robots": [
        RobotChoice(value=f"{shown}#{t}", label=f"{shown}, tool frame {t} (URDF)",
                    kind="urdf").model_dump() for t in frames]}
