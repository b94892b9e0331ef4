"""The checks of the tests' SI table and arrays: required cells finite and plausible,
rotations measured in full or not at all, a load in every test; every error names the
CSV line and column (:mod:`analysis.identification.io.columns`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.io.columns import (
    PLAUSIBLE_MAX,
    R_COLS,
    SI_COLUMNS,
    SI_D,
    SI_Q,
    SI_W,
    TO_SI,
    W_COLS,
)


def validate_table(table: pd.DataFrame, where: str = "measurements") -> None:
    """Check a tidy SI table: columns present, required cells finite, rotations all-or-none.

    Row numbers in messages are the table's ``line`` column when present
    (CSV lines), else 0-based row indices labelled ``row``.
    """
    missing = [c for c in SI_COLUMNS if c not in table.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)}", where=where)
    lines = table["line"].to_numpy() if "line" in table.columns else None
    for col in [*SI_Q, *SI_W, *SI_D]:
        try:
            values = table[col].to_numpy(dtype=float)
        except (TypeError, ValueError) as err:
            raise InputError(f"column {_csv_name(col)} is not numeric", where=where) from err
        _check_column(values, col, lines, where)
    _check_rows(table[SI_D[3:]].to_numpy(dtype=float), table[SI_W].to_numpy(dtype=float),
                lines, where)


def validate_arrays(q: np.ndarray, w: np.ndarray, d: np.ndarray, lines: np.ndarray | None,
                     where: str) -> None:
    """:func:`validate_table` on the (m, 6) SI arrays: the same checks in the same order,
    so that the same cell is named."""
    for block, names in ((q, SI_Q), (w, SI_W), (d, SI_D)):
        for j, col in enumerate(names):
            _check_column(block[:, j], col, lines, where)
    _check_rows(d[:, 3:], w, lines, where)


def _row_label(lines: np.ndarray | None, i: int) -> str:
    return f"line {int(lines[i])}" if lines is not None else f"row {i}"


def _csv_name(si: str) -> str:
    for c, (s, _) in TO_SI.items():
        if s == si:
            return c
    return si


def _check_column(values: np.ndarray, col: str, lines: np.ndarray | None, where: str) -> None:
    """SI column ``col``: a finite number in every row (rotations may be NaN, not
    measured) and within :data:`PLAUSIBLE_MAX`; the first bad row is named."""
    if col in SI_D[3:]:
        bad = np.isinf(values)
    else:
        bad = ~np.isfinite(values)
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        what = "is empty or NaN" if np.isnan(values[i]) else "is not finite"
        raise InputError(
            f"{_row_label(lines, i)}, column {_csv_name(col)}: {what} (a number is required)",
            where=where,
        )
    with np.errstate(invalid="ignore"):
        huge = np.abs(values) > PLAUSIBLE_MAX[col]
    if np.any(huge):
        i = int(np.flatnonzero(huge)[0])
        name = _csv_name(col)
        factor = TO_SI[name][1] if name in TO_SI else 1.0
        raise InputError(
            f"{_row_label(lines, i)}, column {name}: {values[i] / factor:.6g} is beyond any "
            f"plausible value (|value| <= {PLAUSIBLE_MAX[col] / factor:.3g}); check the units "
            "and the cell", where=where)


def _check_rows(rot: np.ndarray, w: np.ndarray, lines: np.ndarray | None, where: str) -> None:
    """Rows: a rotation (m, 3) measured in full or not at all; a wrench (m, 6) not zero."""
    nan = np.isnan(rot)
    partial = nan.any(axis=1) & ~nan.all(axis=1)
    if np.any(partial):
        i = int(np.flatnonzero(partial)[0])
        cols = [R_COLS[j] for j in range(3) if np.isnan(rot[i, j])]
        raise InputError(
            f"{_row_label(lines, i)}, column {', '.join(cols)}: a rotation is either measured "
            "in full (rx, ry, rz) or left empty", where=where,
        )
    zero = np.all(w == 0.0, axis=1)
    if np.any(zero):
        i = int(np.flatnonzero(zero)[0])
        raise InputError(
            f"{_row_label(lines, i)}, columns {', '.join(W_COLS)}: zero wrench; a test needs "
            "a load", where=where,
        )
