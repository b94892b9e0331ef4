"""The files of an identification: results.json (its residual and validation summaries),
residuals.csv and validation.csv."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.identification.io.residual_rows import ResidualRows, histogram

#: results.json lists every held-out pose up to this many; beyond, the worst ones by
#: RMS error / sigma and a summary (every pose stays in validation.csv)
VALIDATION_LISTED = 200


def worst_poses(validation: pd.DataFrame, listed: int = VALIDATION_LISTED) -> pd.DataFrame:
    """The ``listed`` rows of ``validation`` of largest RMS error over the prediction's total
    uncertainty (or over sigma in a table without it; NaN, i.e. folds that could not be
    fitted, first), largest first; all rows in order when there are no more than
    ``listed``."""
    if len(validation) <= listed:
        return validation
    col = "rms_normalized_total" if "rms_normalized_total" in validation else "rms_normalized"
    key = validation[col].to_numpy(dtype=float)
    key = np.where(np.isfinite(key), key, np.inf)
    return validation.iloc[np.argsort(-key, kind="stable")[:listed]]


def validation_summary(validation: pd.DataFrame | None, listed: int = VALIDATION_LISTED) -> dict:
    """results.json entries for the leave-one-pose-out table: ``validation`` (rows; all of
    them up to ``listed`` poses, else the worst ``listed``), ``validation_listed`` (which)
    and ``validation_summary`` (pose count, folds not fitted, median and maximum RMS
    error / sigma, pooled RMS errors)."""
    if validation is None:
        return {"validation": None, "validation_listed": None, "validation_summary": None}
    norm = validation["rms_normalized"].to_numpy(dtype=float)
    n = validation["n_tests"].to_numpy(dtype=float)
    fitted = np.isfinite(norm)

    def pooled(col):  # RMS over the tests of the fitted folds (weights: tests per pose)
        v = validation[col].to_numpy(dtype=float)
        ok = fitted & np.isfinite(v)
        return float(np.sqrt(np.sum(n[ok] * v[ok] ** 2) / np.sum(n[ok]))) if ok.any() else None

    summary = {
        "n_poses": int(len(validation)),
        "folds_not_fitted": int((~fitted).sum()),
        "rms_normalized_median": float(np.median(norm[fitted])) if fitted.any() else None,
        "rms_normalized_max": float(np.max(norm[fitted])) if fitted.any() else None,
        "rms_translation_m_pooled": pooled("rms_translation_m"),
        "rms_rotation_rad_pooled": pooled("rms_rotation_rad"),
    }
    if "rms_normalized_total" in validation:
        from analysis.identification.validation.holdout_check import (
            HOLDOUT_FAMILY_LEVEL,
            LIMIT_TEXT,
        )

        tot = validation["rms_normalized_total"].to_numpy(dtype=float)
        ok = np.isfinite(tot)
        beyond = validation["beyond_limit"].to_numpy(dtype=bool)
        summary.update({
            "rms_normalized_total_median": float(np.median(tot[ok])) if ok.any() else None,
            "rms_normalized_total_max": float(np.max(tot[ok])) if ok.any() else None,
            "n_beyond_limit": int(beyond.sum()),
            "poses_beyond_limit": [str(v) for v in validation["held_out_pose"][beyond]][:100],
            "limit_family_level": HOLDOUT_FAMILY_LEVEL,
            "limit": LIMIT_TEXT,
        })
    rows = worst_poses(validation, listed)
    which = (f"all {len(validation)} held-out poses" if len(rows) == len(validation) else
             f"the {listed} of {len(validation)} held-out poses with the largest RMS error / "
             "total uncertainty (folds not fitted first); every pose is in validation.csv")
    return {"validation": _records(rows), "validation_listed": which,
            "validation_summary": summary}


#: results.json lists every residual up to this many rows; beyond, the largest
#: |studentized| ones and a histogram (all rows stay in residuals.csv)
RESIDUALS_LISTED = 1000


def residual_summary(residuals: pd.DataFrame, listed: int = RESIDUALS_LISTED,
                     rows: ResidualRows | None = None) -> dict:
    """results.json entries for the residual table: ``residuals`` (rows), what they are,
    and a histogram of the studentized residuals.

    Up to ``listed`` rows every row is listed in table order; beyond, the
    ``listed`` rows of largest |studentized| (outliers first), largest first.
    ``rows``: the whole table when ``residuals`` holds only the rows of the worst tests
    (:class:`ResidualRows`); the histogram and the row count are then of every row.
    """
    t = residuals["studentized"].to_numpy(dtype=float)
    finite = np.isfinite(t)
    total = len(residuals) if rows is None else rows.n_rows
    out = {"residual_histogram": histogram(t) if rows is None else rows.histogram()}
    if total <= listed:
        out["residuals_listed"] = f"all {len(residuals)} rows"
        out["residuals"] = _records(residuals)
        return out
    marked = residuals["outlier"].to_numpy(dtype=bool)
    if "set_aside" in residuals:
        marked = marked | residuals["set_aside"].to_numpy(dtype=bool)
    key = np.where(finite, np.abs(t), -1.0) + np.where(marked, np.inf, 0.0)
    top = np.argsort(-key, kind="stable")[:listed]
    out["residuals_listed"] = (f"the {listed} of {total} rows with the largest "
                               "|studentized| (outliers first); every row is in residuals.csv")
    out["residuals"] = _records(residuals.iloc[top])
    return out


def _records(frame: pd.DataFrame) -> list[dict]:
    out = []
    for rec in frame.to_dict(orient="records"):
        clean = {}
        for key, v in rec.items():
            if isinstance(v, (float, np.floating)):
                clean[key] = float(v) if math.isfinite(v) else None
            elif isinstance(v, (np.integer,)):
                clean[key] = int(v)
            elif isinstance(v, (np.bool_,)):
                clean[key] = bool(v)
            else:
                clean[key] = v
        out.append(clean)
    return out


def write_table(table, path: Path) -> None:
    """CSV of ``table`` (a DataFrame or a :class:`ResidualRows`): the bytes of pandas'
    ``to_csv(index=False)`` of the whole table (floats in numpy's shortest round-trip
    text, empty cells for NaN, True/False), written a block of rows at a time by
    :mod:`analysis.identification.io.table_csv` (a 1e6-test residual table, 6e6 rows,
    never exists as one DataFrame)."""
    from analysis.identification.io.table_csv import write_blocks, write_frame
    from analysis.identification.streaming.per_test import release_freed_heap

    if isinstance(table, ResidualRows):
        write_blocks(path, table.names, table.blocks())
    else:
        write_frame(table, path)
    release_freed_heap()  # the blocks' freed text (~20 MB at 1e6 tests), before what follows


def write_results(result, out_dir: str | Path) -> dict[str, Path]:
    """Write ``results.json`` of ``result`` (an
    :class:`~analysis.identification.result.IdentificationResult`), ``residuals.csv``
    (and ``validation.csv``) into ``out_dir``.

    Returns the paths written, by name.
    """
    from analysis.output_files import make_dir, write_text

    out = make_dir(out_dir)
    paths = {"results": out / "results.json", "residuals": out / "residuals.csv"}
    write_text(paths["results"], json.dumps(result.to_dict(), indent=2) + "\n")
    write_table(result.residuals if result.residual_rows is None else result.residual_rows,
                paths["residuals"])
    if result.validation is not None:
        paths["validation"] = out / "validation.csv"
        write_table(result.validation, paths["validation"])
    return paths
