"""``/api/use``: what the Use view offers to pick from the workspace.

The robot models (the built-in names and the ``.toml`` robot or identified model
files), the path CSVs (a header with ``q1_deg``), the workpiece paths of the
placement search (a header with ``x_mm`` and ``ax``) and the analyses
(directories holding a results.json). Paths are relative to the workspace; the walk skips hidden
directories, does not follow symbolic links and stops after :data:`MAX_FILES` files.
"""

from __future__ import annotations

import os
from pathlib import Path

from fastapi import APIRouter, Query, Request
from fastapi.responses import PlainTextResponse
from pydantic import BaseModel

router = APIRouter(prefix="/api/use", tags=["use"])

#: files looked at, at most (a workspace is a few campaigns, not a disk)
MAX_FILES = 5000


class UseFiles(BaseModel):
    """Choices of the Use view (workspace-relative paths)."""

    builtin: list[str]
    models: list[str]
    paths: list[str]
    parts: list[str]
    analyses: list[str]


def _walk(ws: Path):
    seen = 0
    for root, dirs, files in os.walk(ws, followlinks=False):
        dirs[:] = sorted(d for d in dirs if not d.startswith("."))
        for name in sorted(files):
            seen += 1
            if seen > MAX_FILES:
                return
            yield Path(root) / name


def _header(f: Path) -> list[str]:
    try:
        with open(f, encoding="utf-8", errors="replace") as fh:
            head = fh.readline(4096)
    except OSError:
        return []
    return [c.strip() for c in head.split(",")]


def _is_path_csv(cols: list[str]) -> bool:
    """Joint angles of a path: not a compensation's output (``q1_cmd_deg``), nor a tests
    file of a run (its measured displacements, ``dx_mm``: the import format's)."""
    return "q1_deg" in cols and "dx_mm" not in cols and \
        not any(c.endswith("_cmd_deg") for c in cols)


def _is_part_csv(cols: list[str]) -> bool:
    return {"x_mm", "y_mm", "z_mm", "ax", "ay", "az"} <= set(cols) and "q1_deg" not in cols


def _is_robot_toml(f: Path) -> bool:
    """A robot file or an identified model: a ``[[joints]]``/``joints`` table, no protocol."""
    if f.name == "protocol.toml":
        return False
    try:
        text = f.read_text(encoding="utf-8", errors="replace")[:200_000]
    except OSError:
        return False
    return "joints" in text and "[tests]" not in text


@router.get("/files", response_model=UseFiles)
def files(request: Request) -> UseFiles:
    """Robot models, path CSVs, workpiece paths and analyses in the workspace."""
    from analysis.model.robots import builtin_names

    ws = Path(request.app.state.workspace)
    models, paths, parts, analyses = [], [], [], []
    for f in _walk(ws):
        if f.is_symlink():
            continue
        rel = f.relative_to(ws).as_posix()
        if f.suffix == ".toml" and _is_robot_toml(f):
            models.append(rel)
        elif f.suffix == ".csv":
            cols = _header(f)
            if _is_path_csv(cols):
                paths.append(rel)
            elif _is_part_csv(cols):
                parts.append(rel)
        elif f.name == "results.json":
            analyses.append(f.parent.relative_to(ws).as_posix() or ".")
    return UseFiles(builtin=list(builtin_names()), models=models, paths=paths, parts=parts,
                    analyses=analyses)


#: robot programs the compensate job writes (KUKA KRL, ABB RAPID, URScript), served as text
PROGRAM_SUFFIXES = (".src", ".dat", ".mod", ".script")


@router.get("/program", response_class=PlainTextResponse)
def program(request: Request, path: str = Query(..., max_length=1000)) -> PlainTextResponse:
    """A robot program file in the workspace as plain text, byte for byte (the
    compensation's output)."""
    from analysis.errors import InputError
    from campaign.web.security import inside_workspace

    p = inside_workspace(request.app.state.workspace, path, "path")
    if p.suffix.lower() not in PROGRAM_SUFFIXES:
        raise InputError(f"only {', '.join(PROGRAM_SUFFIXES)} programs are served here",
                         where="path")
    if not p.is_file():
        raise InputError("no such file in the workspace", where="path")
    if p.stat().st_size > 20_000_000:
        raise InputError("file too large to serve", where="path")
    # the file's own bytes: a controller's line ends (KRL: CR LF) are not translated
    return PlainTextResponse(p.read_bytes())
