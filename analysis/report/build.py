"""Assemble the report (:class:`analysis.report.document.Report`) from an identification.

SI inside; the tables show kN m/rad, um, urad, mm and degrees, each header
naming its unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.identification.io.columns import COMPONENTS
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.identification.prediction_stiffness import stiffness_for_prediction
from analysis.identification.problem import OUTLIER_FAMILY_LEVEL
from analysis.identification.result import IdentificationResult
from analysis.kinetostatics.map_fixed import MapFixed, map_fixed_joints
from analysis.model.robot_model import RobotModel
from analysis.report import figures
from analysis.report.design_robustness import design_robustness, design_tests
from analysis.report.document import Paragraph, Report, Section, Table, Trace
from analysis.report.formatting import (
    MICRO,
    PM,
    clean,
    eng,
    fixed,
    interval_kNm,
    k_kNm,
    level,
    percent,
    sig,
)
from analysis.report.quantities import (
    deflection_map,
    map_length,
    pose_stiffness,
)
from analysis.report.summary import (
    CampaignInfo,
    approval_table,
    instrument_table,
    partial_text,
    quality_blocks,
    summary_table,
)
from analysis.report.test_table import LoadCase, tests_table
from analysis.report.verdict import outlier_counts, relative_interval, result_blocks

SECTION_TITLES = (
    "Summary",
    "Identified joint stiffness",
    "Residuals and validation",
    "Tests",
    "Deflection under the user wrench",
    "Cartesian stiffness K_X",
    "Robustness of this design",
)
#: up to this many tests, the table of tests is a section after the residuals; beyond,
#: an appendix at the end of the report
TESTS_INLINE = 30
AXES = ["x", "y", "z", "rx", "ry", "rz"]


@dataclass
class ReportInputs:
    """Everything the report needs besides the identification result (SI units).

    Attributes
    ----------
    robot : the robot model (with its tool). tests : the tests identified from.
    info : campaign summary. noise : the noise model used for the identification.
    wrench : (6,) user wrench [N, N m] at P, base frame; wrench_source says where it comes from.
    poses : (label, q (6,) rad) where K_X is reported.
    nominal : (6,) reference stiffness (N m/rad) or None; nominal_label names it,
        nominal_source says where its values come from (e.g. a paper's table).
    true_k : (6,) true stiffness of a simulated lab, or None.
    map_fixed : joint values of the maps (:class:`MapFixed`, or (6,) rad with entries
        2 and 3 ignored; default the median of the tested poses).
    trials : Monte-Carlo trials per number of tests for the robustness curve.
    load_cases : the planned load cases (name, method, wrench), for the table of tests.
    """

    robot: RobotModel
    tests: TestArrays
    info: CampaignInfo
    noise: NoiseModel
    wrench: np.ndarray
    wrench_source: str
    poses: list[tuple[str, np.ndarray]]
    nominal: np.ndarray | None = None
    nominal_label: str = "nominal"
    nominal_source: str = ""
    true_k: np.ndarray | None = None
    map_fixed: MapFixed | np.ndarray | None = None
    trials: int = 300
    load_cases: list[LoadCase] = field(default_factory=list)
    history: Section | None = None


def wrench_text(w: np.ndarray) -> str:
    """``f = (..) N, m = (..) N m`` with 4 significant digits."""
    f = ", ".join(sig(v, 4) for v in w[:3])
    m = ", ".join(sig(v, 4) for v in w[3:])
    return f"f = ({f}) N, m = ({m}) N m"


def map_fixed_of(inp: ReportInputs) -> MapFixed:
    """The maps' fixed joints as a :class:`MapFixed` (given, or by the one rule)."""
    if isinstance(inp.map_fixed, MapFixed):
        return inp.map_fixed
    if inp.map_fixed is None:
        return map_fixed_joints(inp.robot.n, None, inp.tests.q)
    q = np.asarray(inp.map_fixed, dtype=float)
    return MapFixed(q, (), ())


def stiffness_table(result: IdentificationResult, inp: ReportInputs) -> Table:
    """k, interval, standard error, comparison with the nominal (and true) values."""
    conf = f"{level(result.confidence)}"
    short = inp.nominal_label.split(" (")[0]  # "nominal" or "prior"
    cols = ["joint", "k (kN m/rad)", f"{conf} interval (kN m/rad)", "se (kN m/rad)",
            "se/k (%)", f"{inp.nominal_label} (kN m/rad)", f"k/{short} - 1 (%)",
            f"{short} in interval"]
    if inp.true_k is not None:
        cols += ["true (kN m/rad)", "k/true - 1 (%)"]
    rows, marked = [], []
    for j in range(6):
        k = result.k[j]
        nom = inp.nominal[j] if inp.nominal is not None else np.nan
        ident = np.isfinite(k)
        row = [f"k{j + 1}", k_kNm(k) if ident else "not identified",
               interval_kNm(*result.ci[j]) if ident else "-",
               sig(result.se_k[j] / 1e3, 3, zeros=True),
               fixed(100 * result.se_k[j] / k, 2) if ident else "-", k_kNm(nom),
               percent(k / nom - 1) if ident and np.isfinite(nom) else "-"]
        inside = ident and np.isfinite(nom) and bool(result.ci[j, 0] <= nom <= result.ci[j, 1])
        row.append("-" if not (ident and np.isfinite(nom)) else ("yes" if inside else "no"))
        if inp.true_k is not None:
            row += [k_kNm(inp.true_k[j]),
                    percent(k / inp.true_k[j] - 1) if ident else "-"]
        rows.append(row)
        marked.append(False)  # red is for failures; a reference outside is not one
    return Table("Stiffness with standard errors and reference values", cols, rows, marked,
                 caption=(f"{short.capitalize()} values: {inp.nominal_source}. "
                          if inp.nominal_source and inp.nominal is not None else "")
                 + f"'{short} in interval': whether the {inp.nominal_label} value lies inside "
                 f"the {conf} interval (a reference, not a pass/fail test). Interval: {conf} "
                 "interval of the compliance 1/k mapped to k ('inf': the data do not bound "
                 "k from above).",
                 widths=[0.6, 1.1, 1.7, 1.0, 0.8, 1.2, 1.1, 0.8] + ([1.0, 1.0] if inp.true_k
                                                                    is not None else []))


def linear_bias_blocks(result: IdentificationResult) -> list:
    """ols/wls: the raw linear estimate beside the reported (bias-corrected) one, per joint,
    with the criterion of the correction (none for the exact fit)."""
    b = result.linear_bias
    if b is None:
        return []
    m = result.method
    raw, raw_se = b["raw_joint_stiffness_Nm_per_rad"], b["raw_standard_error_Nm_per_rad"]
    rows = []
    for j in range(6):
        if raw[j] is None or not np.isfinite(result.k[j]):
            rows.append([f"k{j + 1}", "-", "-", "-", "-", "-"])
            continue
        rows.append([f"k{j + 1}", k_kNm(result.k[j]), k_kNm(raw[j]),
                     sig(raw_se[j] / 1e3, 3, zeros=True),
                     fixed(b["bias_in_standard_errors"][j], 2),
                     percent(b["relative_change_of_k"][j])])
    verdict = (f"the correction is reliable ({b['criterion']}; value "
               f"{sig(b['contraction'], 2)}, limit {b['contraction_limit']:g}), so k is the "
               "corrected estimate" if b["reliable"] else
               f"the correction is unreliable ({b['reason']}): k is the raw estimate, its "
               "interval widened by |bias|, and the result refused")
    return [Table(
        f"Linearisation bias of {m}: raw and corrected estimates",
        ["joint", "k reported (kN m/rad)", f"raw {m} (kN m/rad)", f"raw {m} se (kN m/rad)",
         "bias of 1/k (raw se)", "corrected vs raw (%)"], rows, [False] * 6,
        caption=f"The linear model A x of {m} is the first-order approximation of the "
        "equilibrium; its bias b = G (f(x) - A x) is estimated and corrected (the "
        f"compliances whose expected linear fit is the one observed). Here {verdict}. "
        "'bias of 1/k': the raw compliance's bias in its standard errors.",
        widths=[0.6, 1.2, 1.2, 1.2, 1.2, 1.2])]


def fit_paragraph(result: IdentificationResult) -> Paragraph:
    return Paragraph(
        f"Method {result.method} ({result.covariance} covariance), {result.n_tests} tests at "
        f"{result.n_poses} poses, {result.n_equations} equations, {result.dof} residual "
        f"degrees of freedom. Reduced chi-square χ²/ν "
        f"{sig(result.chi2_reduced, 3)} "
        f"(p = {sig(result.p_value, 2)}); condition number of the column-scaled A "
        f"{sig(result.condition_number, 3)} (weighted {sig(result.condition_number_weighted, 3)})."
    )


#: the report's residual table lists at most this many tests
REPORT_TESTS_LISTED = 200


def residual_table(result: IdentificationResult) -> Table:
    """One row per test: residual of each measured component (um, urad); '*' marks outliers.

    Beyond :data:`REPORT_TESTS_LISTED` tests, only the tests holding the largest
    |studentized| residuals (outliers first) are listed, in test order; the
    caption says so (every row is in residuals.csv).
    """
    import pandas as pd

    res = all_res = result.residuals
    full = result.residual_rows  # None when result.residuals holds every row
    n_tests = int(all_res["test"].nunique()) if full is None else full.n_tests
    n_rows = len(all_res) if full is None else full.n_rows
    if n_tests > REPORT_TESTS_LISTED:
        t = np.abs(all_res["studentized"].to_numpy(dtype=float))
        marked = all_res["outlier"].to_numpy(dtype=bool)
        if "set_aside" in all_res:
            marked = marked | all_res["set_aside"].to_numpy(dtype=bool)
        key = np.where(np.isfinite(t), t, -1.0) + np.where(marked, np.inf, 0.0)
        worst = all_res["test"].to_numpy()[np.argsort(-key, kind="stable")]
        keep = pd.unique(worst)[:REPORT_TESTS_LISTED]
        res = all_res[all_res["test"].isin(keep)]
    rows, marked = [], []
    daggers = 0
    for test, group in res.groupby("test", sort=True):
        cells = {c: "-" for c in COMPONENTS}
        flag = False
        for _, r in group.iterrows():
            value = 1e6 * r["residual"]
            star = " *" if r["outlier"] else ""
            if r.get("set_aside", False) and not r["outlier"]:
                star += " \u2020"
                daggers += 1
            flag |= bool(r["outlier"])
            cells[r["component"]] = f"{value:.1f}{star}"
        first = group.iloc[0]
        rows.append([str(test + 1), str(first["pose"]), str(first["line"]),
                     *[cells[c] for c in COMPONENTS]])
        marked.append(flag)
    u, ur = f"{MICRO}m", f"{MICRO}rad"
    cols = ["test", "pose", "line", f"dx ({u})", f"dy ({u})", f"dz ({u})", f"rx ({ur})",
            f"ry ({ur})", f"rz ({ur})"]
    mark = (f"* outlier: |studentized residual| > {result.outlier_threshold:.2f} (Sidak, "
            f"{level(OUTLIER_FAMILY_LEVEL)} family-wise over {n_rows} residuals) at the fit "
            "reported" + ("" if not daggers else
                          "; \u2020 set aside by the "
                          + ("sequential outlier test (largest first, refit after each)"
                             if result.robust is None else
                             f"{result.robust['method']} fit (down-weighted below "
                             f"{result.robust['reported_below_weight']:g}, see the robust "
                             "fitting table)")
                          + " but within the threshold"))
    return Table("Residuals (measured - model) per test and component", cols, rows, marked,
                 caption=f"{mark}; highlighted rows hold one. 'line': row of the input table."
                 + ("" if res is all_res and full is None else
                    f" Listed: the {REPORT_TESTS_LISTED} of {n_tests} tests with the largest "
                    "|studentized| residuals (outliers first); every test is in "
                    "residuals.csv."),
                 widths=[0.6, 0.8, 0.6, 1, 1, 1, 1, 1, 1])


def robust_blocks(result: IdentificationResult) -> list:
    """The robust fit's down-weighted components (none for the Gaussian fit)."""
    rob = result.robust
    if rob is None:
        return []
    text = (f"Robust fit: {rob['method']} IRLS, c = {rob['constant']:g} on residuals whitened "
            f"by the noise model's sigma (scale 1), {rob['iterations']} reweighting "
            "iterations; covariance: the M-estimator sandwich with one scale per test "
            "(the test's squared score over its expectation under the noise model), "
            "intervals with Student t"
            + (" (" + ", ".join(f"{v:.3g}" for v in rob["covariance"]["degrees_of_freedom"])
               + " degrees of freedom per joint, Satterthwaite)."
               if rob.get("covariance") else "."))
    if not rob["down_weighted"]:
        return [Paragraph(f"{text} No component down-weighted below "
                          f"{rob['reported_below_weight']:g}.")]
    rows = [[str(d["test"]), str(d["line"]), str(d["pose"]), d["component"],
             f"{d['weight']:.3g}", f"{d['whitened_residual']:.1f}"]
            for d in rob["down_weighted"]]
    return [Paragraph(text), Table(
        "Components down-weighted by the robust fit", ["test", "line", "pose", "component",
                                                         "weight", "residual / sigma"], rows,
        [d["weight"] < 0.1 for d in rob["down_weighted"]],
        caption=f"Components with weight below {rob['reported_below_weight']:g} (1: full "
        "weight, 0: left out); highlighted: below 0.1, effectively discarded. They are left "
        "out of the chi-square and the validation. 'line': row of the input table.")]


def validation_blocks(result: IdentificationResult) -> list:
    if result.validation is None:
        return [Paragraph("Held-out validation needs 3 distinct poses or more: not done.",
                          "note")]
    from analysis.identification.io.results_json import validation_summary, worst_poses
    from analysis.report.verdict import HELD_OUT_LIMIT, _column

    shown = worst_poses(result.validation)
    total = _column(shown, "total")  # the ratio to the total (noise + prediction) sigma
    flag = _column(shown, "flag", dtype=bool)
    limit_col = _column(shown, "limit") if total else None
    rows, marked = [], []
    for _, r in shown.iterrows():
        ratio = r[total] if total else r["rms_normalized"]
        bad = bool(r[flag]) if flag else bool(np.isfinite(ratio) and ratio > HELD_OUT_LIMIT)
        rows.append([str(r["held_out_pose"]), str(r["n_tests"]),
                     fixed(1e6 * r["rms_translation_m"], 1), fixed(1e6 * r["rms_rotation_rad"], 1),
                     fixed(r["rms_normalized"], 2),
                     *([fixed(r[total], 2)] if total else []),
                     *([fixed(r[limit_col], 2)] if limit_col else []),
                     "beyond the limit" if bad else (str(r["note"] or "-"))])
        marked.append(bad)
    limit = ("flagged by the validation's own limit" if flag else
             f"highlighted: above {HELD_OUT_LIMIT:g}")
    return [Table(
        "Held-out validation (leave one pose out)",
        ["held-out pose", "tests", f"RMS error translation ({MICRO}m)",
         f"RMS error rotation ({MICRO}rad)", "RMS error / noise sigma",
         *(["RMS error / total sigma"] if total else []),
         *(["limit"] if limit_col else []), "note"],
        rows, marked, caption="Each pose is predicted from a fit without it; an RMS error / "
        "sigma near 1 means the model predicts unseen poses to within the measurement noise"
        + (" (total sigma: the noise and the prediction's own uncertainty)" if total else
           " (the prediction's own uncertainty is not included)")
        + f"; {limit}."
        + ("" if len(shown) == len(result.validation) else
           f" Shown: {validation_summary(result.validation)['validation_listed']}."),
        widths=[1, 0.6, 1.5, 1.5, 1.3, *([1.3] if total else []),
                *([0.7] if limit_col else []), 1.6]),
    ]


KX_ROWS = ["fx (N)", "fy (N)", "fz (N)", "mx (N m)", "my (N m)", "mz (N m)"]
KX_COLS = ["\u03b4x (per mm)", "\u03b4y (per mm)", "\u03b4z (per mm)", "\u03b4rx (per mrad)",
           "\u03b4ry (per mrad)", "\u03b4rz (per mrad)"]


def kx_engineering(ps, label: str, se_diag: np.ndarray | None) -> list[Table]:
    """K_X (with K_C) in engineering units with its diagonal and standard errors, and the
    table of the principal stiffnesses (translation in N/mm, rotation in N m/mrad).

    Every column is per mm (translation) or per mrad (rotation) of P, every row
    a force (N) or a moment (N m), so each SI entry is scaled by 1e-3: the
    translational block reads in N/mm, the rotational one in N m/mrad.
    """
    from analysis.kinetostatics.uncertainty import principal_stiffness

    pt, pr = principal_stiffness(ps.K_X)
    M = clean(1e-3 * ps.K_X)
    principal = 1e-3 * np.concatenate([pt, pr])
    diag = np.diag(M)
    rows = []
    for i in range(6):
        se = "" if se_diag is None else f" {PM} {sig(1e-3 * se_diag[i], 2)}"
        rows.append([KX_ROWS[i], *[eng(v) for v in M[i]], eng(diag[i]) + se])
    where = pose_title(label, start=False)
    kx = Table(f"K_X at {where}, with K_C",
               ["", *KX_COLS, f"diagonal {PM} se"], rows,
               caption="Row: force (N) or moment (N m) at P; column: translation (mm) or "
               "rotation (mrad) of P, base frame; so the translational block reads in N/mm "
               "and the rotational one in N m/mrad. Standard errors from the covariance of "
               "the identified compliances.",
               widths=[0.8, 0.9, 0.9, 0.9, 0.9, 0.9, 0.9, 1.3], mono=True)
    principal_table = Table(
        f"Principal stiffnesses at {where}", ["load", "largest", "middle", "smallest"],
        [["pure force (N/mm)", *[eng(v) for v in principal[:3]]],
         ["pure moment (N m/mrad)", *[eng(v) for v in principal[3:]]]],
        caption="The stiffness P shows under a pure force or a pure moment along the "
        "principal directions (inverse eigenvalues of the translational and rotational "
        "blocks of K_X\u207b\u00b9), largest first.", widths=[1.6, 1, 1, 1], mono=True)
    return [kx, principal_table]


def kc_effect_table(poses: list) -> Table:
    """What K_C changes: deflection with and without it, relative change of the K_X blocks."""
    rows = []
    for ps in poses:
        d, d0 = ps.deflection, ps.deflection_no_KC
        dp, dp0 = 1e3 * np.linalg.norm(d[:3]), 1e3 * np.linalg.norm(d0[:3])
        diff = 1e3 * np.linalg.norm(d[:3] - d0[:3])
        rel = []
        for sl in (slice(0, 3), slice(3, 6)):
            a, b = ps.K_X[sl, sl], ps.K_X_no_KC[sl, sl]
            rel.append(np.linalg.norm(a - b) / np.linalg.norm(b))
        rows.append([ps.label, eng(dp), eng(dp0), eng(diff),
                     fixed(100 * diff / dp, 2) if dp > 0 else "-",
                     fixed(100 * rel[0], 2), fixed(100 * rel[1], 2)])
    return Table(
        "Effect of K_C (the load's geometric stiffness)",
        ["pose", "|\u03b4p|, load's stiffness included (mm)", "|\u03b4p|, neglected (mm)",
         "|difference| (mm)", "of |\u03b4p| (%)",
         "change, translational block (%)", "change, rotational block (%)"], rows,
        caption="Change of a block: Frobenius norm of K_X(with K_C) - K_X(without) over "
        "that of K_X(without), per diagonal block of K_X. A few % or less: K_C can be "
        "neglected at this load.", widths=[1.6, 1, 1, 1.3, 0.9, 1.1, 1.1])


def kx_blocks(inp: ReportInputs, k_pred: np.ndarray,
              result: IdentificationResult | None = None) -> list:
    blocks: list = [Paragraph(
        "K_X = J\u207b\u1d40 (K_\u03b8 \u2212 K_C) J\u207b\u00b9 (eq. 6), at P in the base "
        f"frame, under the user wrench {wrench_text(inp.wrench)} ({inp.wrench_source}); "
        "K_C is the "
        "complementary stiffness the load adds through the change of J (eq. 12 drops it).")]
    computed = []
    for label, q in inp.poses:
        ps = pose_stiffness(inp.robot, label, q, k_pred, inp.wrench)
        computed.append(ps)
        deg = ", ".join(fixed(v, 2) for v in clean(np.degrees(ps.q), 360.0))
        d = clean(ps.deflection, np.abs(ps.deflection).max())
        dp, dr = 1e3 * d[:3], 1e3 * d[3:]
        blocks.append(Paragraph(
            f"{pose_title(label)}: q = ({deg}) deg (model convention). Deflection of P "
            f"with K_C: \u03b4p = ({', '.join(eng(v, 3) for v in dp)}) mm, |\u03b4p| = "
            f"{eng(float(np.linalg.norm(dp)), 3)} mm; \u03b4\u03c6 = "
            f"({', '.join(eng(v, 3) for v in dr)}) mrad."))
        blocks.extend(kx_engineering(ps, label, _kx_se_diag(inp, q, k_pred, result)))
    if computed:
        blocks.append(kc_effect_table(computed))
    return blocks


def pose_title(label: str, start: bool = True) -> str:
    """'Pose 1' ('pose 1' unless ``start``) for a bare label; a label that already
    says 'pose' is not prefixed again (no 'Pose pose 1')."""
    text = label if label.lower().startswith("pose") else f"pose {label}"
    return text[0].upper() + text[1:] if start else text


def _kx_se_diag(inp: ReportInputs, q: np.ndarray, k: np.ndarray,
                result: IdentificationResult | None) -> np.ndarray | None:
    """Standard errors of diag(K_X) (SI) from the identified compliances' covariance."""
    if result is None:
        return None
    from analysis.kinetostatics.uncertainty import cartesian_stiffness_se, stiffness_covariance
    from analysis.model.kinematics import jacobian

    cov = np.zeros((6, 6))
    cols = list(result.joints)
    cov[np.ix_(cols, cols)] = result.cov_x
    bad = ~np.isfinite(result.k)
    cov[bad], cov[:, bad] = 0.0, 0.0
    try:
        return np.diag(cartesian_stiffness_se(jacobian(inp.robot, q), stiffness_covariance(k, cov)))
    except np.linalg.LinAlgError:
        return None


def robustness_blocks(result: IdentificationResult, inp: ReportInputs,
                      k_ref: np.ndarray) -> list:
    q, w = design_tests(inp.tests.q, inp.tests.w)
    m, n_run = len(q), result.n_tests
    ns = sorted({n for n in (3, 4, 5, 6, 8, 10, 15, 20, m, 2 * m, 3 * m, n_run)
                 if 3 <= n <= max(20, 3 * m, n_run)})
    table = design_robustness(inp.robot, q, w, k_ref, inp.noise, result.joints, tests=ns,
                              trials=inp.trials)
    se_rel = {j + 1: result.se_k[j] / result.k[j] for j in result.joints}
    nz = inp.noise
    noise_text = (f"wls, {inp.trials} trials; noise {sig(1e6 * nz.translation_sigma, 3)} "
                  f"\u00b5m, {sig(1e6 * nz.rotation_sigma, 3)} \u00b5rad, "
                  f"{sig(nz.force_sigma, 3)} N, {sig(nz.moment_sigma, 3)} N m")
    fig = figures.robustness_curve(table, result.n_tests, se_rel, noise_text)
    rows, std_rows = [], []
    for j in sorted(table["joint"].unique()):
        s = table[table["joint"] == j].set_index("n_tests")
        rows.append([f"k{j}", *[sig(100 * s.loc[n, "robust_sigma"], 2)
                                if s.loc[n, "identifiable"] else "n.i." for n in ns]])
        std_rows.append([f"k{j}", *[sig(100 * s.loc[n, "relative_std"], 2)
                                    if s.loc[n, "identifiable"] else "n.i." for n in ns]])
    return [
        Paragraph(f"The campaign's {m} distinct pose/load pairs, each repeated "
                  f"\u230an/{m}\u230b times plus (n mod {m}) of them at random (n < {m}: n "
                  f"of them at random); {inp.trials} trials per point; truth = the "
                  "identified k; noise = the identification's noise model (translation "
                  f"{sig(1e6 * nz.translation_sigma, 3)} \u00b5m, rotation "
                  f"{sig(1e6 * nz.rotation_sigma, 3)} \u00b5rad, force "
                  f"{sig(nz.force_sigma, 3)} N, moment {sig(nz.moment_sigma, 3)} N m per "
                  "component); batched weighted least squares on the linear model. At n = "
                  "this campaign's size the curve should meet its reported standard errors "
                  "(stars)."),
        fig,
        Table("Spread of k (IQR / 1.349, % of k) against the number of tests",
              ["joint", *[f"n = {n}" for n in ns]], rows,
              caption="Interquartile range of k / k_ref over 1.349 (the standard deviation "
              "of a normal spread). n.i.: not identifiable at that number of tests (more "
              "than 10 % of the trials give no positive k, or the spread exceeds 100 %)."),
        Table("Standard deviation of k (% of k), where identifiable",
              ["joint", *[f"n = {n}" for n in ns]], std_rows,
              caption="The plain standard deviation over the trials (with the median and "
              "IQR above: a few wild draws inflate it at small n)."),
    ]


def build_report(result: IdentificationResult, inp: ReportInputs) -> Report:
    """Assemble the report's sections (runs the maps and the Monte-Carlo study)."""
    from analysis.report.traceability import software_text, utc_now_text

    k_pred, pred_notes = stiffness_for_prediction(result.k, inp.nominal)
    length, length_source = map_length(inp.robot)
    mf = map_fixed_of(inp)
    table = deflection_map(inp.robot, k_pred, inp.wrench, mf.q, length)
    wt = wrench_text(inp.wrench)
    ft = mf.values_text()
    rule = mf.rule_text()
    labels = list(dict.fromkeys(inp.tests.pose.tolist()))
    first = [int(np.flatnonzero(inp.tests.pose == lab)[0]) for lab in labels]
    q_poses = inp.tests.q[first]
    run_notes = [t for t in [partial_text(inp.info)] if t]
    if inp.info.n_failed:
        run_notes.append(f"{inp.info.n_failed} failed test row(s): see Data quality")
    banner = list(run_notes)
    for problem in result.misfit_accepted:
        banner.append(f"ACCEPTED DESPITE A REFUSAL (--accept-misfit): {problem}")
    d = table["deflection_mm"].to_numpy()
    d = d[np.isfinite(d)]
    ident = [j for j in result.joints if np.isfinite(result.k[j])]
    spans = ", ".join(f"k{j + 1} {relative_interval(result.k[j], *result.ci[j])}"
                      for j in ident)
    answer = Paragraph(
        f"Joints {', '.join(str(j + 1) for j in ident)} identified from {result.n_tests} "
        f"tests; {level(result.confidence)} intervals relative to k: {spans}. Under {wt} "
        f"({inp.wrench_source}) the predicted deflection of P over the (\u03b8\u2082, "
        f"\u03b8\u2083) map ranges from {eng(d.min(), 3)} to {eng(d.max(), 3)} mm (median "
        f"{eng(float(np.median(d)), 3)} mm)." if d.size else "")
    short = inp.nominal_label.split(" (")[0]
    test_rows, rms_table = tests_table(inp.robot, inp.tests, result, inp.load_cases, inp.noise,
                                       inp.nominal, short, inp.info.repeatability_mm)
    instruments = instrument_table(inp.info)
    summary = Section(SECTION_TITLES[0], [
        *result_blocks(result, inp.nominal, inp.nominal_label, robot_text(inp.info),
                       inp.info.campaign, inp.info.started_utc, inp.info.report_id, run_notes),
        *[Paragraph(t, "refusal" if t.startswith("ACCEPTED") else "warning")
          for t in banner if not t.startswith("ACCEPTED")],
        answer, approval_table(), *assumption_blocks(result),
        summary_table(inp.info), *([instruments] if instruments is not None else []),
        Paragraph("Data quality", "heading"), *quality_blocks(inp.info)])
    ident_sec = Section(SECTION_TITLES[1], [
        stiffness_table(result, inp), *linear_bias_blocks(result), fit_paragraph(result),
        *[Paragraph(w, "warning") for w in result.warnings],
        *([rms_table] if rms_table is not None else []),
        figures.stiffness_bars(result.k, result.ci, inp.nominal, inp.nominal_label,
                               result.confidence)])
    flagged, aside = outlier_counts(result)
    resid_sec = Section(SECTION_TITLES[2], [
        residual_table(result), figures.residual_plot(
            result.residuals, result.outlier_threshold,
            None if result.residual_rows is None else result.residual_rows.n_tests,
            flagged=flagged, set_aside=aside, robust=result.robust is not None),
        *robust_blocks(result), *validation_blocks(result)])
    defl_sec = Section(SECTION_TITLES[4], [
        Paragraph(f"User wrench at P, base frame: {wt} ({inp.wrench_source}). Prediction "
                  "with the identified k and K_C (linear, eq. 6)."),
        *[Paragraph(n, "note") for n in pred_notes],
        Paragraph(f"1/\u03ba_F of J_N with L = {length:.3f} m ({length_source})."),
        figures.poses_on_kappa_map(table, q_poses, labels, ft, rule),
        figures.deflection_joint_map(table, q_poses, wt, ft, labels, rule),
        figures.deflection_cartesian_map(table, wt)])
    kx_sec = Section(SECTION_TITLES[5], kx_blocks(inp, k_pred, result))
    rob_sec = Section(SECTION_TITLES[6], robustness_blocks(result, inp, k_pred))
    tests_sec = Section(SECTION_TITLES[3] if inp.tests.m <= TESTS_INLINE
                        else f"Appendix: {SECTION_TITLES[3].lower()}",
                        [pose_table(labels, q_poses), test_rows])
    sections = [summary, ident_sec, resid_sec]
    if inp.history is not None:
        sections.insert(2, inp.history)
    if inp.tests.m <= TESTS_INLINE:
        sections.append(tests_sec)
    sections += [defl_sec, kx_sec, rob_sec]
    if inp.tests.m > TESTS_INLINE:
        sections.append(tests_sec)
    title = f"Joint stiffness of {inp.robot.name}"
    subtitle = f"{inp.info.source}: {inp.info.location}"
    return Report(title, subtitle, sections, banner, simulated=inp.info.simulated,
                  trace=Trace(inp.info.report_id, utc_now_text(), software_text()))


def robot_text(info: CampaignInfo) -> str:
    """The robot's name with its serial when the protocol or the controller gives one."""
    for rec in info.instrument_records:
        if rec.get("role") == "robot" and rec.get("serial"):
            return f"{info.robot} (serial {rec['serial']})"
    return info.robot


def pose_table(labels: list[str], q: np.ndarray) -> Table:
    """The tested poses: plan label and joint angles (deg, model convention)."""
    rows = [[str(lab), *[fixed(v, 2) for v in clean(np.degrees(qi), 360.0)]]
            for lab, qi in zip(labels, q, strict=True)]
    return Table("Tested poses", ["pose", *[f"\u03b8{j} (deg)" for j in range(1, 7)]], rows,
                 caption="Joint angles of each tested pose (model convention), as measured "
                 "at its first test.", widths=[1, 1, 1, 1, 1, 1, 1])


def misfit_causes_text(record: dict) -> str:
    """The cause tests of a misfit (results.json ``assumptions.misfit_causes``) in one line:
    each alternative's F, dof and p-value, ranked; the ones not tested and why."""
    if "skipped" in record:
        return f"none: {record['skipped']}"
    parts = [f"{c['cause'].replace('_', ' ')} F = {sig(c['F'], 3)} ({c['dof'][0]}, "
             f"{c['dof'][1]}), p = {c['p_value']:.2g}" + (" *" if c.get("named", c["significant"])
                                                    else "")
             for c in record["ranked"]]
    parts += [f"{c['cause'].replace('_', ' ')} not tested ({c['why']})"
              for c in record["not_tested"]]
    return "; ".join(parts) + (f" (ranked by evidence; * named: significant at "
                               f"{record['level']:g}, and beyond the first cause)")


def assumption_blocks(result: IdentificationResult) -> list:
    """The table of what the result rests on (empty when the caller recorded nothing)."""
    a = result.assumptions
    if not a:
        return []
    rows = []
    if "robot" in a:
        rows.append(["robot", str(a["robot"])])
    if "tool_point" in a:
        t = a["tool_point"]
        rows.append(["tool point P", f"xyz {t['xyz_mm']} mm, rpy {t['rpy_deg']} deg in the "
                                     f"flange frame ({t['source']})"])
    if "noise" in a:
        n = a["noise"]
        rows.append(["noise per test row",
                     f"translation {sig(n['translation_sigma_um'], 3)} \u00b5m, rotation "
                     f"{sig(n['rotation_sigma_urad'], 3)} \u00b5rad, force "
                     f"{sig(n['force_sigma_N'], 3)} N, moment {sig(n['moment_sigma_Nm'], 3)} N m "
                     f"({n['source']})"])
    if "misfit_causes" in a:
        rows.append(["causes of the misfit tested", misfit_causes_text(a["misfit_causes"])])
    for key in ("method", "robust", "covariance", "joints", "poses"):
        # the default Gaussian fit needs no row of its own: the method row says it
        if key == "joints":  # what was done, not the rule that chose it
            rigid = [str(j + 1) for j in range(6) if j not in result.joints]
            rows.append(["joints identified", ", ".join(str(j + 1) for j in result.joints)
                         + (f" (taken as rigid: {', '.join(rigid)})" if rigid else "")])
        elif key in a and not (key == "robust" and str(a[key]).startswith("none")):
            rows.append([key, str(a[key])])
    from analysis.report.model_classes import model_class_blocks

    return [Table("Assumptions", ["item", "value"], rows, widths=[1, 3.2]),
            *model_class_blocks(a.get("model_classes"))]
