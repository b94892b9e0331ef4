"""``GET /api/analyze/plots``: the Analyze view's residual and validation plots, as read.

Nothing is recomputed: the numbers are those the analyze job wrote into
``RUN/analysis`` -- the residual table ``residuals.csv`` (every row: studentized
residual, residual and its sigma in SI, the outlier flag of the reported fit, the
components the sequential test set aside and, for a robust fit, the weight) with the
outlier threshold of ``results.json`` (``outlier_threshold_studentized``), and the
held-out validation of ``results.json`` (``validation``: per held-out pose the RMS
prediction error over the total uncertainty ``rms_normalized_total`` against
``limit_normalized_total``, the flag ``beyond_limit``, and the RMS error over the noise
alone ``rms_normalized``). Above :data:`MAX_POINTS` residual rows the plot gets the rows
``results.json`` lists (the largest |studentized|) and says so.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from fastapi import APIRouter, Depends, HTTPException, Query

from campaign.web.api_jobs import inside, workspace

router = APIRouter(prefix="/api/analyze", tags=["analyze-plots"])
#: residual rows sent to the page at most (a browser plot of more is no longer readable)
MAX_POINTS = 60_000
RESIDUAL_COLUMNS = ("test", "pose", "component", "unit", "residual", "sigma", "studentized",
                    "outlier", "set_aside", "weight")
VALIDATION_FIELDS = ("held_out_pose", "n_tests", "rms_normalized", "rms_normalized_total",
                     "limit_normalized_total", "p_value_total", "beyond_limit",
                     "rms_translation_m", "rms_rotation_rad", "note")


def _number(v):
    """A float for JSON: None for NaN, inf, empty cells and text."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _flag(v) -> bool:
    return v is True or str(v).strip().lower() == "true"


def _rows(path: Path) -> int:
    """Data rows of a CSV file (its lines less the header), counted without parsing."""
    lines = 0
    with open(path, "rb") as f:
        while chunk := f.read(1 << 20):
            lines += chunk.count(b"\n")
    return max(lines - 1, 0)


def residual_table(records: list[dict]) -> dict:
    """Residual records (residuals.csv rows or results.json ``residuals``) as columns."""
    out: dict[str, list] = {c: [] for c in RESIDUAL_COLUMNS}
    for r in records:
        out["test"].append(_number(r.get("test")))
        out["pose"].append(str(r.get("pose", "")))
        out["component"].append(str(r.get("component", "")))
        out["unit"].append(str(r.get("unit", "")))
        for c in ("residual", "sigma", "studentized", "weight"):
            out[c].append(_number(r.get(c)))
        out["outlier"].append(_flag(r.get("outlier")))
        out["set_aside"].append(_flag(r.get("set_aside")))
    return out


def _residuals(analysis: Path, results: dict) -> tuple[dict, int, str]:
    """(columns, rows in the analysis, which rows are shown)."""
    import csv

    path = analysis / "residuals.csv"
    if path.is_file():
        total = _rows(path)
        if total <= MAX_POINTS:
            with open(path, newline="", encoding="utf-8") as f:
                return residual_table(list(csv.DictReader(f))), total, f"all {total} rows"
    else:
        total = None
    listed = [r for r in results.get("residuals") or [] if isinstance(r, dict)]
    total = total if total is not None else len(listed)
    shown = (f"all {total} rows" if len(listed) == total else
             f"{len(listed)} of {total} rows, the largest |studentized| (results.json)")
    return residual_table(listed), total, shown


def validation_rows(results: dict) -> list[dict]:
    """results.json ``validation`` with the plotted fields (None where not given)."""
    rows = results.get("validation")
    rows = [r for r in rows if isinstance(r, dict)] if isinstance(rows, list) else []
    out = []
    for r in rows:
        rec = {k: r.get(k) for k in VALIDATION_FIELDS}
        rec["held_out_pose"] = str(rec["held_out_pose"])
        for k in VALIDATION_FIELDS[1:-1]:
            if k != "beyond_limit":
                rec[k] = _number(rec[k])
        rec["beyond_limit"] = _flag(r.get("beyond_limit"))
        out.append(rec)
    return out


@router.get("/plots")
def plots(run_dir: str = Query(..., min_length=1, max_length=1000),
          ws: Path = Depends(workspace)) -> dict:
    """The residual and validation plots' numbers of ``RUN_DIR/analysis`` (as written)."""
    run = inside(ws, run_dir, "run_dir")
    analysis = run / "analysis"
    try:
        results = json.loads((analysis / "results.json").read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise HTTPException(404, f"{run_dir}: not analysed yet (no analysis/results.json)"
                            ) from None
    except (OSError, ValueError, UnicodeDecodeError) as err:
        raise HTTPException(400, f"{run_dir}/analysis/results.json: not readable ({err})"
                            ) from None
    if not isinstance(results, dict):
        raise HTTPException(400, f"{run_dir}/analysis/results.json: not a JSON object")
    try:
        res, total, shown = _residuals(analysis, results)
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise HTTPException(400, f"{run_dir}/analysis/residuals.csv: not readable ({err})"
                            ) from None
    summary = results.get("validation_summary") or {}
    return {"run_dir": run_dir, "method": results.get("method"),
            "robust": results.get("robust"),
            "threshold": _number(results.get("outlier_threshold_studentized")),
            "residuals": res, "residual_rows": total, "residuals_shown": shown,
            "validation": validation_rows(results),
            "validation_listed": results.get("validation_listed"),
            "validation_limit": summary.get("limit") if isinstance(summary, dict) else None,
            "poses_beyond_limit": summary.get("poses_beyond_limit")
            if isinstance(summary, dict) else None}
