"""Assemble the report (:class:`analysis.report.model.Report`) from an identification.

SI inside; the tables show kN m/rad, um, urad, mm and degrees, each header
naming its unit.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.identification.estimate import OUTLIER_FAMILY_LEVEL
from analysis.identification.measurements import COMPONENTS, TestArrays
from analysis.identification.noise import NoiseModel
from analysis.identification.result import IdentificationResult
from analysis.model.robot_model import RobotModel
from analysis.report import figures
from analysis.report.design_robustness import design_robustness, design_tests
from analysis.report.formatting import (
    MICRO,
    fixed,
    interval_kNm,
    k_kNm,
    matrix_entry,
    percent,
    sig,
)
from analysis.report.model import Paragraph, Report, Section, Table
from analysis.report.quantities import (
    deflection_map,
    map_length,
    pose_stiffness,
    stiffness_for_prediction,
)
from analysis.report.summary import CampaignInfo, partial_text, quality_blocks, summary_table

SECTION_TITLES = (
    "Summary",
    "Identified joint stiffness",
    "Residuals and validation",
    "Deflection under the user wrench",
    "Cartesian stiffness K_X",
    "Robustness of this design",
)
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
    nominal : (6,) reference stiffness (N m/rad) or None; nominal_label names it.
    true_k : (6,) true stiffness of a simulated lab, or None.
    map_fixed : (6,) joint values of the maps (rad; entries 2 and 3 ignored).
    trials : Monte-Carlo trials per number of tests for the robustness curve.
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
    true_k: np.ndarray | None = None
    map_fixed: np.ndarray = field(default_factory=lambda: np.radians([0, 0, 0, 45, 45, 45]))
    trials: int = 300


def wrench_text(w: np.ndarray) -> str:
    """``f = (..) N, m = (..) N m`` with 4 significant digits."""
    f = ", ".join(sig(v, 4) for v in w[:3])
    m = ", ".join(sig(v, 4) for v in w[3:])
    return f"f = ({f}) N, m = ({m}) N m"


def fixed_text(q: np.ndarray) -> str:
    deg = np.degrees(q)
    return ", ".join(f"\u03b8{i + 1} = {deg[i]:.0f}" for i in (0, 3, 4, 5)) + " deg"


def stiffness_table(result: IdentificationResult, inp: ReportInputs) -> Table:
    """k, interval, standard error, comparison with the nominal (and true) values."""
    conf = f"{result.confidence:.0%}"
    cols = ["joint", "k (kN m/rad)", f"{conf} interval (kN m/rad)", "se (kN m/rad)",
            "se/k (%)", f"{inp.nominal_label} (kN m/rad)", "k/nominal - 1 (%)"]
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
        if inp.true_k is not None:
            row += [k_kNm(inp.true_k[j]),
                    percent(k / inp.true_k[j] - 1) if ident else "-"]
        rows.append(row)
        outside = ident and np.isfinite(nom) and not (result.ci[j, 0] <= nom <= result.ci[j, 1])
        marked.append(bool(outside))
    return Table("Identified joint stiffness", cols, rows, marked,
                 caption=f"Highlighted: the {inp.nominal_label} value lies outside the "
                 f"{conf} interval. Interval: {conf} interval of the compliance 1/k mapped "
                 "to k ('inf': the data do not bound k from above).",
                 widths=[0.6, 1.1, 1.7, 1.0, 0.8, 1.2, 1.1] + ([1.0, 1.0] if inp.true_k
                                                               is not None else []))


def fit_paragraph(result: IdentificationResult) -> Paragraph:
    return Paragraph(
        f"Method {result.method} ({result.covariance} covariance), {result.n_tests} tests at "
        f"{result.n_poses} poses, {result.n_equations} equations, {result.dof} residual "
        f"degrees of freedom. Reduced chi-square {sig(result.chi2_reduced, 3)} "
        f"(p = {sig(result.p_value, 2)}); condition number of the column-scaled A "
        f"{sig(result.condition_number, 3)} (weighted {sig(result.condition_number_weighted, 3)})."
    )


def residual_table(result: IdentificationResult) -> Table:
    """One row per test: residual of each measured component (um, urad); '*' marks outliers."""
    res = result.residuals
    rows, marked = [], []
    for test, group in res.groupby("test", sort=True):
        cells = {c: "-" for c in COMPONENTS}
        flag = False
        for _, r in group.iterrows():
            value = 1e6 * r["residual"]
            star = " *" if r["outlier"] else ""
            flag |= bool(r["outlier"])
            cells[r["component"]] = f"{value:.1f}{star}"
        first = group.iloc[0]
        rows.append([str(test + 1), str(first["pose"]), str(first["line"]),
                     *[cells[c] for c in COMPONENTS]])
        marked.append(flag)
    u, ur = f"{MICRO}m", f"{MICRO}rad"
    cols = ["test", "pose", "line", f"dx ({u})", f"dy ({u})", f"dz ({u})", f"rx ({ur})",
            f"ry ({ur})", f"rz ({ur})"]
    return Table("Residuals (measured - model) per test and component", cols, rows, marked,
                 caption=f"* outlier: |studentized residual| > {result.outlier_threshold:.2f} "
                 f"(Sidak, {OUTLIER_FAMILY_LEVEL:.0%} family-wise over {len(res)} residuals); "
                 "highlighted rows hold an outlier. 'line': row of the input table.",
                 widths=[0.6, 0.8, 0.6, 1, 1, 1, 1, 1, 1])


def validation_blocks(result: IdentificationResult) -> list:
    if result.validation is None:
        return [Paragraph("Held-out validation needs 3 distinct poses or more: not done.",
                          "note")]
    rows = []
    for _, r in result.validation.iterrows():
        rows.append([str(r["held_out_pose"]), str(r["n_tests"]),
                     fixed(1e6 * r["rms_translation_m"], 1), fixed(1e6 * r["rms_rotation_rad"], 1),
                     fixed(r["rms_normalized"], 2), str(r["note"]) or "-"])
    return [Table(
        "Held-out validation (leave one pose out)",
        ["held-out pose", "tests", f"RMS error translation ({MICRO}m)",
         f"RMS error rotation ({MICRO}rad)", "RMS error / sigma (1)", "note"],
        rows, caption="Each pose is predicted from a fit without it; an RMS error / sigma "
        "near 1 means the model predicts unseen poses to within the measurement noise.",
        widths=[1, 0.6, 1.5, 1.5, 1.3, 2]),
    ]


def kx_engineering(ps, label: str, se_diag: np.ndarray | None) -> Table:
    """K_X (with K_C) in engineering units: N/mm and N m/mrad blocks, principal stiffnesses."""
    from analysis.kinetostatics.uncertainty import principal_stiffness

    pt, pr = principal_stiffness(ps.K_X)
    rows = []
    for i, (unit, sl) in enumerate((("N/mm", slice(0, 3)), ("N m/mrad", slice(3, 6)))):
        diag = 1e-3 * np.diag(ps.K_X)[sl]
        se = None if se_diag is None else 1e-3 * se_diag[sl]
        for a in range(3):
            row = [AXES[3 * i + a], unit,
                   *[f"{1e-3 * v:.4g}" for v in ps.K_X[sl, sl][a]],
                   f"{diag[a]:.4g}" + ("" if se is None else f" \u00b1 {se[a]:.2g}"),
                   f"{1e-3 * (pt if i == 0 else pr)[a]:.4g}"]
            rows.append(row)
    header = ["", "unit", "x / rx", "y / ry", "z / rz", "diagonal \u00b1 se", "principal"]
    return Table(f"K_X at {label}, with K_C, engineering units", header, rows,
                 caption="Translational block in N/mm, rotational block in N m/mrad. "
                 "Principal stiffnesses: under a pure force (moment) along the principal "
                 "directions, the inverses of the eigenvalues of the blocks of K_X^-1. "
                 "Standard errors from the covariance of the identified compliances.",
                 widths=[0.4, 0.8, 1, 1, 1, 1.4, 1], mono=True)


def kx_blocks(inp: ReportInputs, k_pred: np.ndarray,
              result: IdentificationResult | None = None) -> list:
    blocks: list = [Paragraph(
        f"K_X = J^-T (K_\u03b8 - K_C) J^-1 (eq. 6) and without K_C (eq. 12), at P in the base "
        f"frame, under the user wrench {wrench_text(inp.wrench)}. Units: rows/columns x, y, z "
        "and rx, ry, rz; blocks N/m (translation), N m/rad (rotation), N/rad and N (mixed).")]
    for label, q in inp.poses:
        ps = pose_stiffness(inp.robot, label, q, k_pred, inp.wrench)
        deg = ", ".join(f"{v:.2f}" for v in np.degrees(ps.q))
        dp, dp0 = 1e3 * ps.deflection[:3], 1e3 * ps.deflection_no_KC[:3]
        blocks.append(Paragraph(
            f"Pose {label}: q = ({deg}) deg (model convention). Deflection of P: "
            f"({', '.join(f'{v:.4f}' for v in dp)}) mm with K_C, "
            f"({', '.join(f'{v:.4f}' for v in dp0)}) mm without; |\u03b4p| = "
            f"{np.linalg.norm(dp):.4f} mm."))
        for title, M in (("with K_C", ps.K_X), ("without K_C", ps.K_X_no_KC)):
            rows = [[AXES[i], *[matrix_entry(v) for v in M[i]]] for i in range(6)]
            blocks.append(Table(f"K_X at {label}, {title} (SI)", ["", *AXES], rows,
                                widths=[0.5] + [1] * 6, mono=True))
        blocks.append(kx_engineering(ps, label, _kx_se_diag(inp, q, k_pred, result)))
    return blocks


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
    fig = figures.robustness_curve(table, result.n_tests, se_rel)
    rows = []
    for j in sorted(table["joint"].unique()):
        s = table[table["joint"] == j].set_index("n_tests")["relative_std"]
        rows.append([f"k{j}", *[fixed(100 * s[n], 2) for n in ns]])
    return [
        Paragraph(f"The campaign's {m} distinct pose/load pairs, each repeated n // {m} "
                  f"times plus n mod {m} of them at random (n < {m}: n of them at random); "
                  f"{inp.trials} trials per point; truth = the identified k; noise = the "
                  "identification's noise model; batched least squares on the linear model "
                  "weighted by the displacement sigmas. At n = this campaign's size the "
                  "curve should meet its reported standard errors (stars)."),
        fig,
        Table("Relative standard deviation of k (%) against the number of tests",
              ["joint", *[f"n = {n}" for n in ns]], rows),
    ]


def build_report(result: IdentificationResult, inp: ReportInputs) -> Report:
    """Assemble the report's sections (runs the maps and the Monte-Carlo study)."""
    k_pred, pred_notes = stiffness_for_prediction(result.k, inp.nominal)
    length, length_source = map_length(inp.robot)
    table = deflection_map(inp.robot, k_pred, inp.wrench, inp.map_fixed, length)
    wt = wrench_text(inp.wrench)
    ft = fixed_text(inp.map_fixed)
    labels = list(dict.fromkeys(inp.tests.pose.tolist()))
    first = [int(np.flatnonzero(inp.tests.pose == lab)[0]) for lab in labels]
    q_poses = inp.tests.q[first]
    banner = [t for t in [partial_text(inp.info)] if t]
    for problem in result.misfit_accepted:
        banner.append(f"ACCEPTED DESPITE A REFUSAL (--accept-misfit): {problem}")
    if inp.info.n_failed:
        banner.append(f"{inp.info.n_failed} failed test row(s): see Data quality.")
    d = table["deflection_mm"].to_numpy()
    d = d[np.isfinite(d)]
    ident = [j for j in result.joints if np.isfinite(result.k[j])]
    half = [(result.ci[j, 1] - result.ci[j, 0]) / 2 / result.k[j] for j in ident]
    answer = Paragraph(
        f"Joints {', '.join(str(j + 1) for j in ident)} identified from {result.n_tests} "
        f"tests; 95 % intervals span {pm_text(min(half, default=np.nan))} to "
        f"{pm_text(max(half, default=np.nan))} of k. Under {wt} the predicted deflection of "
        f"P over the (\u03b8\u2082, \u03b8\u2083) map ranges from {fixed(d.min(), 3)} to "
        f"{fixed(d.max(), 3)} mm (median {fixed(np.median(d), 3)} mm)." if d.size else "")
    summary = Section(SECTION_TITLES[0], [
        *[Paragraph(t, "warning") for t in banner], *assumption_blocks(result), answer,
        summary_table(inp.info),
        Paragraph("Data quality", "heading"), *quality_blocks(inp.info)])
    ident_sec = Section(SECTION_TITLES[1], [
        stiffness_table(result, inp), fit_paragraph(result),
        *[Paragraph(w, "warning") for w in result.warnings],
        figures.stiffness_bars(result.k, result.ci, inp.nominal, inp.nominal_label,
                               result.confidence)])
    resid_sec = Section(SECTION_TITLES[2], [
        residual_table(result), figures.residual_plot(result.residuals, result.outlier_threshold),
        *validation_blocks(result)])
    defl_sec = Section(SECTION_TITLES[3], [
        Paragraph(f"User wrench at P, base frame: {wt} ({inp.wrench_source}). Prediction "
                  "with the identified k and K_C (linear, eq. 6)."),
        *[Paragraph(n, "note") for n in pred_notes],
        Paragraph(f"1/\u03ba_F of J_N with L = {length:.3f} m ({length_source})."),
        figures.poses_on_kappa_map(table, q_poses, labels, ft),
        figures.deflection_joint_map(table, q_poses, wt, ft),
        figures.deflection_cartesian_map(table, wt)])
    kx_sec = Section(SECTION_TITLES[4], kx_blocks(inp, k_pred, result))
    rob_sec = Section(SECTION_TITLES[5], robustness_blocks(result, inp, k_pred))
    title = f"Joint stiffness of {inp.robot.name}"
    subtitle = f"{inp.info.source}: {inp.info.location}"
    return Report(title, subtitle, [summary, ident_sec, resid_sec, defl_sec, kx_sec, rob_sec],
                  banner)


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
    for key in ("method", "covariance", "joints", "poses"):
        if key in a:
            rows.append([key, str(a[key])])
    return [Table("Assumptions", ["item", "value"], rows, widths=[1, 3.2])]


def pm_text(value: float) -> str:
    """A relative half-width as '\u00b1x.xx %'."""
    return "-" if not np.isfinite(value) else f"\u00b1{100 * value:.2f} %"
