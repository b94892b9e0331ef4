"""``/api/use/deflection``: the deflection of P along a path, with its 95 % band.

The path is a CSV of the workspace (``path``) or one uploaded in the request
(``upload_name`` and ``upload_text``, at most :data:`MAX_UPLOAD` characters).
Either is read by the command line's path reader (:func:`campaign.use.path_file.read_path`,
through the ``path_deflection`` job), so a bad file gets its ``file:line``
message: an upload is written for the reader under ``.gui/uploads/`` in the
workspace, named as uploaded, and removed once read; its messages name it by
that name alone. Nothing else is written.
"""

from __future__ import annotations

import dataclasses
import re
import secrets
import shutil
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, Depends
from fastapi.responses import JSONResponse
from pydantic import Field

from campaign.jobs.path_deflection import PathDeflectionOptions
from campaign.web.api_jobs import answer, inside, robot_path, workspace

router = APIRouter(prefix="/api/use", tags=["use"])

#: characters of an uploaded path file at most (a 20 000-point path is about 2 MB)
MAX_UPLOAD = 2_000_000
NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}\.csv")


@dataclass(frozen=True)
class PathDeflectionRequest(PathDeflectionOptions):
    """The path_deflection job's options (SI: N, N m; a tool point as the protocol's
    ``[tool]`` gives it, mm and deg), with robot a built-in name or a workspace
    model/robot file and path a workspace path CSV, or instead upload_name (a file name
    ending in .csv) with upload_text (its content)."""

    path: str | None = None
    upload_name: str | None = field(default=None, kw_only=True)
    upload_text: Annotated[str | None, Field(max_length=MAX_UPLOAD)] = field(
        default=None, kw_only=True)


def _refused(field: str, text: str) -> JSONResponse:
    return JSONResponse({"detail": f"{field}: {text}", "field": field, "options": {}},
                        status_code=400)


@router.post("/deflection")
def deflection(req: PathDeflectionRequest, ws: Path = Depends(workspace)) -> JSONResponse:
    """Per point of the path: the deflection screw of P (m, rad; base frame), its 95 %
    interval (an identified model's covariance; null without), |dp| and its upper bound."""
    from campaign.jobs.path_deflection import run

    upload = req.upload_text is not None
    if upload == (req.path is not None):
        return _refused("path", "give a workspace path, or upload_name and upload_text")
    folder = None
    if upload:
        name = req.upload_name or ""
        if not NAME.fullmatch(name):
            return _refused("upload_name", f"{name[:60]!r} is not a file name ending in .csv "
                                           "(letters, digits, . _ -)")
        uploads = inside(ws, ".gui/uploads", "upload_name")  # a link out of it is refused
        folder = uploads / secrets.token_hex(8)
        folder.mkdir(parents=True)
        path = folder / name
        path.write_text(req.upload_text, encoding="utf-8")
    else:
        path = inside(ws, req.path, "path")
    shared = {f.name: getattr(req, f.name) for f in dataclasses.fields(PathDeflectionOptions)}
    options = PathDeflectionOptions(**{**shared, "robot": robot_path(ws, req.robot),
                                       "path": path})
    try:
        answered = answer(ws, lambda: run(options), options)
    finally:
        if folder is not None:
            shutil.rmtree(folder, ignore_errors=True)
    if folder is not None and answered.status_code != 200:
        # the reader named the file by where it was written: by its name alone here
        answered.body = answered.body.replace(
            f"{folder.relative_to(ws).as_posix()}/".encode(), b"")
        answered.headers["content-length"] = str(len(answered.body))
    return answered
