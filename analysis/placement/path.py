"""Part path files: one row per tool-path point in the workpiece frame.

Columns (CSV, header on line 1): ``x_mm, y_mm, z_mm`` (point P, workpiece frame),
``ax, ay, az`` (tool axis, from the tool into the part; normalised if within 1 %
of unit length) and optionally ``fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm`` (process
wrench on the tool at P, tool-frame components). Other columns are ignored.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError

POS_COLS = ("x_mm", "y_mm", "z_mm")
AXIS_COLS = ("ax", "ay", "az")
WRENCH_COLS = ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm")


@dataclass(frozen=True)
class PartPath:
    """A tool path in the workpiece frame (SI).

    points (N, 3) m; axes (N, 3) unit tool axes; wrench (N, 6) [N, N m] in the
    tool frame, or None when the file has no wrench columns; line (N,) file line
    of each point.
    """

    points: np.ndarray
    axes: np.ndarray
    wrench: np.ndarray | None
    line: np.ndarray
    source: str = ""

    @property
    def n(self) -> int:
        return self.points.shape[0]


def read_part_path(path: str | Path) -> PartPath:
    """Read and check a part path CSV; errors name the file, line and column."""
    path = Path(path)
    if not path.is_file():
        raise InputError("part path file not found", where=str(path))
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.reader(fh))
    except (OSError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read the file ({err})", where=str(path)) from None
    if not rows:
        raise InputError("empty file: expected a header x_mm,y_mm,z_mm,ax,ay,az", where=str(path))
    header = [h.strip() for h in rows[0]]
    missing = [c for c in POS_COLS + AXIS_COLS if c not in header]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)} in the header", where=f"{path}:1")
    present = [c for c in WRENCH_COLS if c in header]
    if present and len(present) != 6:
        raise InputError("a wrench needs all six columns fx_N,fy_N,fz_N,mx_Nm,my_Nm,mz_Nm "
                         f"(found {', '.join(present)})", where=f"{path}:1")
    cols = list(POS_COLS + AXIS_COLS) + (list(WRENCH_COLS) if present else [])
    index = [header.index(c) for c in cols]
    values, lines = [], []
    for lineno, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        out = []
        for c, i in zip(cols, index, strict=True):
            cell = row[i].strip() if i < len(row) else ""
            try:
                v = float(cell)
            except ValueError:
                raise InputError(f"column {c}: {cell!r} is not a number",
                                 where=f"{path}:{lineno}") from None
            if not math.isfinite(v):
                raise InputError(f"column {c}: {cell!r} is not finite", where=f"{path}:{lineno}")
            out.append(v)
        values.append(out)
        lines.append(lineno)
    if not values:
        raise InputError("no path points after the header", where=str(path))
    data = np.array(values)
    axes = data[:, 3:6]
    norm = np.linalg.norm(axes, axis=1)
    bad = np.flatnonzero(np.abs(norm - 1.0) > 0.01)
    if bad.size:
        raise InputError(f"tool axis (ax, ay, az) has length {norm[bad[0]]:.4g}: expected a unit "
                         "vector", where=f"{path}:{lines[bad[0]]}")
    return PartPath(
        points=1e-3 * data[:, :3],
        axes=axes / norm[:, None],
        wrench=data[:, 6:12] if present else None,
        line=np.array(lines),
        source=str(path),
    )
