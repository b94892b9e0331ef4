"""The result block at the top of the report: key facts, k with intervals, one verdict line.

The verdict is one of three kinds (:class:`Verdict`):

- ``refusal``: a check refused the result and ``--accept-misfit`` kept it:
  "ACCEPTED DESPITE A REFUSAL" with the refusal (red);
- ``warning``: no refusal, but warnings (outliers, a held-out pose beyond its
  limit, a partial run, failed rows, the identification's warnings);
- ``verdict``: "Consistent with the noise model" with chi-square/nu, p, the
  outlier count and the held-out check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.result import IdentificationResult
from analysis.report.document import Paragraph, Table
from analysis.report.formatting import fixed, interval_kNm, k_kNm, level, percent, sig

#: RMS error / sigma of a held-out pose above which the verdict warns, when the
#: validation table carries no flag of its own (noise-only normalisation)
HELD_OUT_LIMIT = 2.0


@dataclass
class HeldOut:
    """The held-out check as the validation table gives it."""

    text: str
    flagged: list[str]


#: the validation's columns of the total-uncertainty check, when it gives them
#: (:mod:`analysis.identification.validation.holdout_check`): ratio, per-pose limit, flag
TOTAL_COLUMNS = ("rms_normalized_total", "limit_normalized_total", "beyond_limit")


def _column(frame, *needles: str, dtype=None) -> str | None:
    """The column named by the first of :data:`TOTAL_COLUMNS` that is ``needles[0]``'s
    (exact name), else the first whose name holds every needle (and has ``dtype``)."""
    exact = {"total": TOTAL_COLUMNS[0], "limit": TOTAL_COLUMNS[1], "flag": TOTAL_COLUMNS[2]}
    name = exact.get(needles[0]) if len(needles) == 1 else None
    if name is not None and name in frame.columns:
        return name
    for c in frame.columns:
        name = str(c).lower()
        if all(n in name for n in needles) and (dtype is None or frame[c].dtype == dtype):
            return str(c)
    return None


def held_out(result: IdentificationResult) -> HeldOut | None:
    """Median and worst held-out RMS error / sigma and the poses beyond the limit.

    Uses the validation's total-uncertainty ratio (a column naming ``total``) and its
    flag (a boolean column naming ``flag``) when present, else ``rms_normalized``
    against :data:`HELD_OUT_LIMIT`."""
    v = result.validation
    if v is None or len(v) == 0:
        return None
    total = _column(v, "total")
    col = total or "rms_normalized"
    ratio = v[col].to_numpy(dtype=float)
    flag_col = _column(v, "flag", dtype=bool)
    ok = np.isfinite(ratio)
    limit_col = _column(v, "limit") if total else None
    if flag_col is not None:
        bad = v[flag_col].to_numpy(dtype=bool)
        limit = "flagged beyond its limit by the validation"
        if limit_col is not None:
            lim = v[limit_col].to_numpy(dtype=float)
            if np.isfinite(lim).any():
                limit = (f"limits {fixed(float(np.nanmin(lim)), 2)} to "
                         f"{fixed(float(np.nanmax(lim)), 2)}, Sidak" if np.nanmin(lim)
                         != np.nanmax(lim) else f"limit {fixed(float(lim[0]), 2)}, Sidak")
    else:
        bad = ok & (ratio > HELD_OUT_LIMIT)
        limit = f"limit {HELD_OUT_LIMIT:g}"
    poses = v["held_out_pose"].astype(str).to_numpy()
    flagged = [f"pose {p} ({fixed(r, 2)})" for p, r, b in zip(poses, ratio, bad, strict=True)
               if b]
    what = ("RMS error / total sigma (noise and prediction)" if total else
            "RMS error / noise sigma")
    if not ok.any():
        return HeldOut(f"{len(v)} held-out poses, none could be fitted", flagged)
    worst = int(np.nanargmax(np.where(ok, ratio, -np.inf)))
    text = (f"{len(v)} held-out poses: {what} median {fixed(float(np.median(ratio[ok])), 2)}, "
            f"max {fixed(ratio[worst], 2)} (pose {poses[worst]}; {limit})")
    return HeldOut(text, flagged)


def outlier_counts(result: IdentificationResult) -> tuple[int, int]:
    """(outliers: residuals with |studentized| beyond the stated threshold at the fit
    reported, i.e. the ``outlier`` rows; residuals the fit set aside: ``set_aside``)."""
    rows = result.residual_rows
    if rows is not None:  # the whole table as arrays: (m, 6), NaN where not measured
        return rows.n_beyond(), int((rows.flags & rows.tests.measured).sum())
    res = result.residuals
    t = np.abs(res["studentized"].to_numpy(dtype=float))
    beyond = int(np.sum(np.isfinite(t) & (t > result.outlier_threshold)))
    aside = res["set_aside"] if "set_aside" in res else res["outlier"]
    return beyond, int(aside.to_numpy(dtype=bool).sum())


@dataclass
class Verdict:
    """``kind``: ``verdict``, ``warning`` or ``refusal``; ``text``: the one line."""

    kind: str
    text: str


def verdict(result: IdentificationResult, notes: list[str]) -> Verdict:
    """The one-line verdict; ``notes``: the run's own warnings (partial run, failed rows)."""
    flagged, aside = outlier_counts(result)
    what = "down-weighted" if result.robust is not None else "set aside by the outlier test"
    stats = (f"\u03c7\u00b2/\u03bd {sig(result.chi2_reduced, 3)}, p {sig(result.p_value, 2)}; "
             f"{flagged} outlier(s) (|studentized residual| > "
             f"{fixed(result.outlier_threshold, 2)})"
             + (f", {aside} {what}" if aside != flagged else ""))
    ho = held_out(result)
    stats += f"; {ho.text}" if ho is not None else "; no held-out check (fewer than 3 poses)"
    if result.misfit_accepted:
        return Verdict("refusal", "ACCEPTED DESPITE A REFUSAL (--accept-misfit): "
                       + " | ".join(result.misfit_accepted) + f". {stats}.")
    problems = list(notes)
    if flagged:
        problems.append(f"{flagged} residual(s) beyond the outlier threshold")
    if ho is not None and ho.flagged:
        problems.append("held-out " + ", ".join(ho.flagged) + " beyond the limit")
    problems += result.warnings
    if problems:
        return Verdict("warning", "Warnings: " + "; ".join(problems) + f". {stats}.")
    return Verdict("verdict", f"Consistent with the noise model: {stats}; no refusal "
                   "overridden.")


def relative_interval(k: float, lo: float, hi: float) -> str:
    """The interval relative to k: '-1.23 % / +1.45 %' (asymmetric as it is)."""
    if not np.isfinite(k) or not np.isfinite(lo):
        return "-"
    up = "+inf" if not np.isfinite(hi) else percent(hi / k - 1)
    return f"{percent(lo / k - 1)} / {up} %"


def result_table(result: IdentificationResult, nominal: np.ndarray | None,
                 nominal_label: str) -> Table:
    """k with its interval (absolute and relative to k) and the reference value."""
    conf = f"{level(result.confidence)}"
    short = nominal_label.split(" (")[0]
    rows = []
    for j in range(6):
        k = result.k[j]
        ident = np.isfinite(k)
        nom = nominal[j] if nominal is not None else np.nan
        rows.append([f"k{j + 1}", k_kNm(k) if ident else "not identified (rigid)",
                     interval_kNm(*result.ci[j]) if ident else "-",
                     relative_interval(k, *result.ci[j]) if ident else "-",
                     k_kNm(nom) if np.isfinite(nom) else "-",
                     percent(k / nom - 1) if ident and np.isfinite(nom) else "-"])
    return Table(f"Result: joint stiffness k with {conf} intervals",
                 ["joint", "k (kN m/rad)", f"{conf} interval (kN m/rad)",
                  "interval - k (% of k)", f"{short} (kN m/rad)", f"k/{short} - 1 (%)"],
                 rows, caption=f"The interval is asymmetric (that of the compliance 1/k "
                 "mapped to k): its two sides are given separately. "
                 f"{short.capitalize()}: {nominal_label}.",
                 widths=[0.6, 1.2, 1.8, 1.5, 1.1, 1.0])


def facts_text(robot: str, campaign: str, started: str, report_id: str) -> str:
    """The key facts line: robot, campaign, date of the measurements, report ID."""
    parts = [f"Robot: {robot}"]
    if campaign:
        parts.append(f"campaign: {campaign}")
    if started and started != "-":
        parts.append(f"measured: {started[:10]}")
    if report_id:
        parts.append(f"report ID: {report_id}")
    return " \u00b7 ".join(parts)


def result_blocks(result: IdentificationResult, nominal, nominal_label: str, robot: str,
                  campaign: str, started: str, report_id: str, notes: list[str]) -> list:
    """The facts line, the verdict line and the k table (the report's first blocks)."""
    v = verdict(result, notes)
    return [Paragraph(facts_text(robot, campaign, started, report_id), "facts"),
            Paragraph(v.text, v.kind), result_table(result, nominal, nominal_label)]
