"""Path files for ``campaign compensate``: one row per point, commanded joints and process wrench.

Columns (CSV, header on line 1): ``q1_deg .. q6_deg`` (commanded joints, model
convention, or the pendant's with ``--controller-angles``) and optionally
``fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm`` (process wrench at P, base frame, or
the tool frame with ``--wrench-frame tool``). Other columns are carried over
to the output unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.model.kinematics import tool_pose
from analysis.model.robot_model import RobotModel

Q_COLS = [f"q{i}_deg" for i in range(1, 7)]
W_COLS = ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]


@dataclass
class PathInput:
    """A path read and converted to SI (model convention, base frame).

    frame : the CSV as read (pandas DataFrame); q (N, 6) commanded joints (rad,
    model convention); w (N, 6) wrench at P in the base frame (N, N m); line
    (N,) CSV line of each point; wrench_source : where the wrench came from.
    """

    frame: object
    q: np.ndarray
    w: np.ndarray
    line: np.ndarray
    wrench_source: str


def where_row(path: Path, line: int) -> str:
    """``file:line (point i)`` for messages (i counts data rows from 1)."""
    return f"{path}:{line} (point {line - 1})"


def _duplicated_column(path: Path) -> str | None:
    """The first column name given twice in the CSV header (pandas renames the second
    ``q1_deg.1`` and would silently use the first), or None."""
    import csv

    with path.open(newline="", encoding="utf-8-sig", errors="replace") as fh:
        header = next(csv.reader(fh), [])
    seen: set[str] = set()
    for name in (h.strip() for h in header):
        if name in seen:
            return name
        seen.add(name)
    return None


def read_path(path: Path, robot: RobotModel, controller: bool, wrench: np.ndarray | None,
              wrench_frame: str) -> PathInput:
    """Read and check PATH.csv; refuse (naming the line and column) anything unusable."""
    import pandas as pd

    if wrench_frame not in ("base", "tool"):
        raise InputError("expected base or tool", where="--wrench-frame")
    if not path.is_file():
        raise InputError("path file not found", where=str(path))
    try:
        frame = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise InputError(f"not a readable CSV file: {err}", where=str(path)) from None
    duplicated = _duplicated_column(path)
    if duplicated:
        raise InputError(f"column {duplicated!r} appears more than once in the header: "
                         "which one is meant is a guess; keep one", where=f"{path}:1")
    missing = [c for c in Q_COLS if c not in frame.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)} (expected q1_deg..q6_deg)",
                         where=str(path))
    if len(frame) == 0:
        raise InputError("no points in the path file", where=str(path))
    line = np.arange(len(frame)) + 2
    has_w = [c for c in W_COLS if c in frame.columns]
    if has_w and len(has_w) != 6:
        raise InputError(f"wrench columns {', '.join(has_w)} given without the others "
                         f"(expected all of {', '.join(W_COLS)})", where=str(path))
    if has_w and wrench is not None:
        raise InputError("the path file has wrench columns: drop --wrench, or the columns",
                         where="--wrench")
    if not has_w and wrench is None:
        raise InputError(f"no wrench: add the columns {', '.join(W_COLS)} to the path file or "
                         "give --wrench fx,fy,fz,mx,my,mz", where="--wrench")
    cols = Q_COLS + (W_COLS if has_w else [])
    values = frame[cols].apply(pd.to_numeric, errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if np.any(bad):
        i, j = np.argwhere(bad)[0]
        raise InputError(f"column {cols[j]}: {frame[cols[j]].iloc[i]!r} is not a finite number",
                         where=where_row(path, int(line[i])))
    q = np.radians(values[:, :6])
    if controller:
        q = robot.from_controller(q)
    w = values[:, 6:] if has_w else np.broadcast_to(wrench, (len(frame), 6)).copy()
    source = "path file columns" if has_w else "the wrench given (constant)"
    if wrench_frame == "tool":
        R = tool_pose(robot, q)[:, :3, :3]
        w = np.concatenate([np.einsum("nij,nj->ni", R, w[:, :3]),
                            np.einsum("nij,nj->ni", R, w[:, 3:])], axis=1)
        source += ", tool frame rotated to the base frame at the target pose of each point"
    else:
        source += ", base frame"
    return PathInput(frame, q, w, line, source)
