"""The report's table of the tests: what was done and what each test shows, before and after.

One row per test identified from: its pose, load case (name and how it was
applied), planned and measured wrench, measured deflection, repeatability,
and the residual norm under the nominal (or prior) model beside that under
the identified one, the before/after of a calibration report. SI inside; the
table shows N, N m, mm, mrad, um and urad, each header naming its unit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.io.columns import COMPONENTS
from analysis.identification.io.measurements import TestArrays
from analysis.report.document import Table
from analysis.report.formatting import MICRO, fixed, level, sig

#: the table lists at most this many tests (every test is in residuals.csv)
TESTS_LISTED = 2000
#: a measured wrench belongs to a load case when each of its force and moment
#: differs from the case's by at most this fraction of the case's norm plus 5 sigmas
LOAD_MATCH_RELATIVE = 0.10


@dataclass
class LoadCase:
    """A planned load case: name, how it is applied, wrench (6,) [N, N m] at P, base frame."""

    name: str
    method: str
    wrench: np.ndarray


def match_load_cases(w: np.ndarray, cases: list[LoadCase], force_sigma: float,
                     moment_sigma: float) -> np.ndarray:
    """Index into ``cases`` of the load case of each measured wrench (m, 6), -1 for none:
    the nearest case whose force and moment both agree within
    :data:`LOAD_MATCH_RELATIVE` of its norm plus 5 noise sigmas."""
    w = np.atleast_2d(np.asarray(w, dtype=float))
    out = np.full(len(w), -1)
    if not cases:
        return out
    c = np.array([lc.wrench for lc in cases], dtype=float)  # (n, 6)
    df = np.linalg.norm(w[:, None, :3] - c[None, :, :3], axis=2)
    dm = np.linalg.norm(w[:, None, 3:] - c[None, :, 3:], axis=2)
    tol_f = LOAD_MATCH_RELATIVE * np.linalg.norm(c[:, :3], axis=1) + 5 * force_sigma
    tol_m = LOAD_MATCH_RELATIVE * np.linalg.norm(c[:, 3:], axis=1) + 5 * moment_sigma
    ok = (df <= tol_f) & (dm <= tol_m)
    score = np.where(ok, df / np.maximum(tol_f, 1e-12) + dm / np.maximum(tol_m, 1e-12), np.inf)
    best = np.argmin(score, axis=1)
    hit = np.isfinite(score[np.arange(len(w)), best])
    out[hit] = best[hit]
    return out


def identified_prediction(result, m: int) -> np.ndarray:
    """(m, 6) displacement the identified model predicts per test (NaN where not measured)."""
    rows = result.residual_rows
    if rows is not None:
        return np.where(rows.tests.measured, rows.predicted, np.nan)
    out = np.full((m, 6), np.nan)
    res = result.residuals
    comp = res["component"].astype(str).map({c: i for i, c in enumerate(COMPONENTS)})
    out[res["test"].to_numpy(dtype=int), comp.to_numpy(dtype=int)] = \
        res["predicted"].to_numpy(dtype=float)
    return out


def nominal_prediction(robot, tests: TestArrays, k_nominal: np.ndarray | None,
                       rows: np.ndarray) -> np.ndarray | None:
    """(len(rows), 6) displacement under the nominal stiffness (nonlinear equilibrium), or
    None without a nominal."""
    if k_nominal is None or not np.all(np.isfinite(k_nominal)):
        return None
    from analysis.kinetostatics.equilibrium import displacement_screw

    return displacement_screw(robot, tests.q[rows], np.asarray(k_nominal, float),
                              tests.w[rows])


def _norms(r: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation norm (m) and rotation norm (rad) of (n, 6) rows, NaN when none measured."""
    def norm(block):
        ok = np.isfinite(block)
        value = np.sqrt(np.sum(np.where(ok, block, 0.0) ** 2, axis=1))
        return np.where(ok.any(axis=1), value, np.nan)

    return norm(r[:, :3]), norm(r[:, 3:])


def rms_pair(r: np.ndarray) -> tuple[float, float]:
    """RMS over the measured components: translation (m), rotation (rad)."""
    out = []
    for block in (r[:, :3], r[:, 3:]):
        ok = np.isfinite(block)
        out.append(float(np.sqrt(np.mean(block[ok] ** 2))) if ok.any() else float("nan"))
    return out[0], out[1]


def _pair(a: float, b: float, scale: float, decimals: int) -> str:
    return f"{fixed(scale * a, decimals)} / {fixed(scale * b, decimals)}"


def tests_table(robot, tests: TestArrays, result, cases: list[LoadCase], noise,
                k_nominal: np.ndarray | None, nominal_short: str,
                repeatability: dict[int, float]) -> tuple[Table, Table | None]:
    """(the table of tests, the before/after RMS table or None without a nominal)."""
    m = tests.m
    rows_idx = np.arange(min(m, TESTS_LISTED))
    pred_id = identified_prediction(result, m)
    d = np.where(tests.measured, tests.d, np.nan)
    pred_nom = nominal_prediction(robot, tests, k_nominal, np.arange(m) if m <= TESTS_LISTED
                                  else rows_idx)
    res_id = d - pred_id
    rid_t, rid_r = _norms(res_id[rows_idx])
    if pred_nom is not None:
        res_nom = d[: len(pred_nom)] - np.where(tests.measured[: len(pred_nom)], pred_nom,
                                                 np.nan)
        rn_t, rn_r = _norms(res_nom[rows_idx])
    which = match_load_cases(tests.w[rows_idx], cases, noise.force_sigma, noise.moment_sigma)
    dp, dr = _norms(d[rows_idx])
    out = []
    for n, i in enumerate(rows_idx):
        c = which[n]
        case = cases[c] if c >= 0 else None
        f_meas, m_meas = np.linalg.norm(tests.w[i, :3]), np.linalg.norm(tests.w[i, 3:])
        plan_f = "-" if case is None else sig(float(np.linalg.norm(case.wrench[:3])), 4)
        plan_m = "-" if case is None else sig(float(np.linalg.norm(case.wrench[3:])), 4)
        rep = repeatability.get(int(tests.line[i]), float("nan"))
        out.append([
            str(i + 1), str(int(tests.line[i])), str(tests.pose[i]),
            "-" if case is None else f"{case.name} ({case.method})",
            f"{plan_f} / {sig(float(f_meas), 4)}", f"{plan_m} / {sig(float(m_meas), 4)}",
            fixed(1e3 * dp[n], 3), fixed(1e3 * dr[n], 3), fixed(rep, 3),
            "-" if pred_nom is None else _pair(rn_t[n], rn_r[n], 1e6, 1),
            _pair(rid_t[n], rid_r[n], 1e6, 1)])
    u = f"{MICRO}m / {MICRO}rad"
    listed = ("" if m <= TESTS_LISTED else
              f" Listed: the first {TESTS_LISTED} of {m} tests; every test is in "
              "residuals.csv.")
    table = Table(
        "Tests: what was done and what each shows",
        ["test", "line", "pose", "load case (method)", "|f| planned / measured (N)",
         "|m| planned / measured (N m)", "|\u03b4p| measured (mm)",
         "|\u03b4\u03c6| measured (mrad)", "repeat- ability (mm)",
         f"residual, {nominal_short} model ({u})", f"residual, identified ({u})"], out,
        caption="One row per test identified from, in the order of the input ('line': its "
        "row in the input table). Load case: the planned case whose force and moment the "
        f"measured wrench matches within {level(LOAD_MATCH_RELATIVE)} plus 5 noise sigmas "
        "('-': none). Residual: norm of measured - predicted translation and rotation of P, "
        f"under the {nominal_short} stiffness (nonlinear equilibrium) and under the "
        "identified one." + listed,
        widths=[0.5, 0.55, 0.7, 1.5, 1.2, 1.2, 0.9, 0.9, 0.8, 1.3, 1.3])
    if pred_nom is None:
        return table, None
    before = rms_pair(res_nom)
    after = rms_pair(res_id[: len(res_nom)])
    sig_t, sig_r = noise.translation_sigma, noise.rotation_sigma
    # 3 significant digits, as the noise figures of the Assumptions table ("36.7 um")
    rows = [["translation (\u00b5m)", *(sig(1e6 * v, 3, zeros=True)
                                         for v in (before[0], after[0], sig_t))],
            ["rotation (\u00b5rad)", *(sig(1e6 * v, 3, zeros=True)
                                        for v in (before[1], after[1], sig_r))]]
    rms = Table(f"Residual RMS: {nominal_short} model against identified",
                ["component", f"{nominal_short} stiffness", "identified stiffness",
                 "noise sigma of one component"], rows,
                caption="RMS over every measured component of the tests"
                + ("" if m <= TESTS_LISTED else f" listed above (first {TESTS_LISTED})")
                + f" of measured - predicted displacement of P, under the {nominal_short} "
                "stiffness and under the identified one; the identified model should come "
                "down to the noise sigma.", widths=[1.2, 1, 1, 1.3])
    return table, rms
