"""Plan directories: ``plan.csv``, the protocol copy, ``plan_map.png``, ``summary.txt/json``.

``plan.csv`` is byte-reproducible: fixed float formats, fixed column order,
no time stamps (the summary holds none either).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from analysis.errors import InputError
from campaign.protocol import Protocol, load_protocol

if TYPE_CHECKING:
    from campaign.planning.planner import Plan

PLAN_FILE = "plan.csv"

#: columns of plan.csv, in order (angles in degrees, wrench in N and N m, base frame)
COLUMNS = (
    ["test", "pose", "zone", "load_case", "method", "repeats"]
    + [f"q{j}_model_deg" for j in range(1, 7)]
    + [f"q{j}_ctrl_deg" for j in range(1, 7)]
    + ["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]
    + ["inv_kappa_F", "v_p", "v_r_deg"]
)


def format_frame(df: pd.DataFrame) -> str:
    """CSV text of a plan table with fixed float formats (byte-reproducible)."""
    out = df.copy()
    fixed3 = [c for c in out.columns if c.endswith(("_deg", "_N", "_N_m")) and c != "v_r_deg"]
    for col in fixed3:
        out[col] = [f"{v:.3f}" for v in out[col]]
    out["inv_kappa_F"] = [f"{v:.6f}" for v in out["inv_kappa_F"]]
    for col in ("v_p", "v_r_deg"):
        out[col] = [f"{v:.6e}" for v in out[col]]
    return out.to_csv(index=False, lineterminator="\n")


def _se_rows(plan: Plan) -> list[dict]:
    rows = []
    for j in range(plan.robot.n):
        k = float(plan.k_prior[j])
        a, b = float(plan.chosen.se[j]), float(plan.random.se[j])
        rows.append({
            "joint": j + 1,
            "k_prior_N_m_per_rad": k,
            "se_design_N_m_per_rad": a,
            "se_design_percent": 100 * a / k,
            "se_random_N_m_per_rad": b,
            "se_random_percent": 100 * b / k,
            "random_over_design": b / a if a > 0 else float("inf"),
            **({} if plan.random_median_se is None else {
                "se_random_median_percent": 100 * float(plan.random_median_se[j]) / k}),
        })
    return rows


def _noise_dict(plan: Plan) -> dict:
    """The noise model of one test row the predictions use, and the sources left at default."""
    from campaign.run_noise import undeclared_sources

    if plan.noise is None:
        return {}
    return {"noise_model_per_row": plan.noise.describe(),
            "noise_defaults_used": undeclared_sources(plan.protocol)}


def _criterion_dict(plan: Plan) -> dict:
    """Worst joint's relative se: design vs the median of 201 random zone designs."""
    if plan.random_median_se is None:
        return {}
    mine = float(np.max(plan.chosen.se / plan.k_prior))
    ref = float(np.max(plan.random_median_se / plan.k_prior))
    out = {"worst_joint": {
        "design_percent": 100 * mine, "random_median_percent": 100 * ref,
        "reduction_percent": 100 * (1 - mine / ref),
        "joint_design": int(np.argmax(plan.chosen.se / plan.k_prior)) + 1,
        "joint_random": int(np.argmax(plan.random_median_se / plan.k_prior)) + 1}}
    if plan.weights is not None:
        out["weights"] = [float(v) for v in plan.weights]
    if plan.case_contributions is not None:
        out["load_case_contributions"] = plan.case_contributions
    return out


def _separation_dict(plan: Plan) -> dict:
    """The minimum joint-space separation of distinct poses, its source, the closest pair."""
    from campaign.planning.separation import min_pairwise_distance

    thresholds = plan.protocol.thresholds
    given = "min_pose_separation_deg" in thresholds.model_fields_set
    q_deg = np.degrees(plan.candidates.q[np.unique(plan.chosen.pose)])
    closest = min_pairwise_distance(q_deg)
    return {"pose_separation": {
        "min_deg": float(thresholds.min_pose_separation_deg),
        "source": ("protocol [thresholds] min_pose_separation_deg" if given else
                   "default (the protocol has no [thresholds] min_pose_separation_deg)"),
        "closest_pair_deg": closest if np.isfinite(closest) else None}}


def _flanks_dict(plan: Plan) -> dict:
    """Gear flank changes of each test (reference under the load case's preload, or none,
    then loaded), from the robot file's gravity model; {} for a robot without masses, and
    for a protocol that neither preloads its load cases nor simulates lost motion (its
    summary stays as it was before lost motion was modelled)."""
    from campaign.planning.flanks import flank_changes, keeping_preload

    protocol = plan.protocol
    lost = protocol.fake_lab is not None and protocol.fake_lab.lost_motion_rad is not None
    if plan.robot.inertials is None or not (protocol.preloaded or lost):
        return {}
    q = plan.candidates.q[plan.chosen.pose]
    w = plan.protocol.wrenches()[plan.chosen.case]
    w_ref = plan.protocol.reference_wrenches()[plan.chosen.case]
    change = flank_changes(plan.robot, q, w, w_ref)
    keep = keeping_preload(plan.robot, q, w)
    return {"gear_flanks": {
        "changes": int(change.sum()),
        "tests_with_changes": int(np.any(change, axis=1).sum()),
        "joints_per_test": [[int(j) + 1 for j in np.flatnonzero(row)] for row in change],
        "preload_fraction_keeping_flanks": [None if not np.isfinite(v) else float(v)
                                            for v in keep],
        "masses": plan.robot.inertials.source or "robot file"},
        **_alias_dict(plan)}


def _alias_dict(plan: Plan) -> dict:
    """The k bias (first order, %) the joint-only fit of the design and of the random zone
    design would take from the protocol's assumed link compliances ({} without)."""
    from campaign.planning.link_alias import design_alias, protocol_links

    links = protocol_links(plan.protocol, plan.robot)
    if not links or plan.noise is None:
        return {}
    out = {}
    for name, d in (("design", plan.chosen), ("random_zone_design", plan.random)):
        a = design_alias(plan.protocol, plan.robot, plan.candidates.q[d.pose], d.case,
                         plan.k_prior, plan.noise.displacement_sigma, links)
        out[name] = [None if not np.isfinite(v) else float(v * 100) for v in a]
    return {"link_compliance_alias_percent": {
        **out, "links": [lc.link for lc in links],
        "what": "k error (first order) of the joint-only fit if the links had the "
                "compliances of the protocol's [fake_lab] links (ASSUMED)"}}


def summary_dict(plan: Plan) -> dict:
    """Everything the summary files hold (plain types, no time stamps)."""
    cand = plan.candidates
    protocol = plan.protocol
    return {
        "protocol": {"name": protocol.campaign.name, "file": Path(protocol.path).name,
                     "sha256": hashlib.sha256(protocol.text.encode()).hexdigest()},
        "robot": plan.robot.name,
        "strategy": plan.strategy,
        "seed": plan.seed,
        "tests": int(len(plan.chosen.pose)),
        "poses": int(len(np.unique(plan.chosen.pose))),
        "candidates": {
            "drawn": int(cand.q.shape[0]),
            "poses_passing": int(np.sum(np.any(cand.valid, axis=1))),
            "rejected": dict(cand.rejected),
        },
        **_separation_dict(plan),
        "characteristic_length_m": plan.length,
        "measurement_sigma_per_test": {
            "translation_m": float(plan.sigma[0]), "rotation_rad": float(plan.sigma[3])},
        "design": {"log_det": plan.chosen.log_det, "min_eig": plan.chosen.min_eig},
        "random_zone_design": {"log_det": plan.random.log_det, "min_eig": plan.random.min_eig},
        "predicted_standard_errors": _se_rows(plan),
        **_noise_dict(plan),
        **_criterion_dict(plan),
        **_flanks_dict(plan),
        **_model_dict(plan),
    }


def _model_dict(plan: Plan) -> dict:
    """The model class's predictions ({} for the joint springs: the summary as before)."""
    if plan.chosen.model is None:
        return {}
    from campaign.planning.model_class import describe

    rec = describe(plan.chosen.model, plan.random.model, plan.chosen.joint_se, plan.k_prior)
    if plan.tests_raised is not None:
        rec["tests_raised"] = plan.tests_raised.describe()
    return {"model_class": rec}


def summary_text(plan: Plan) -> str:
    """Human-readable summary: candidates, rejections, predicted standard errors of k."""
    from analysis.report.formatting import k_kNm, sig

    s = summary_dict(plan)
    c = s["candidates"]
    lines = [
        f"{s['protocol']['name']} ({s['robot']})",
        f"strategy {s['strategy']}, seed {s['seed']}: {s['tests']} tests on {s['poses']} poses",
        f"candidates: {c['drawn']} drawn, {c['poses_passing']} pass the thresholds; rejected: "
        + ", ".join(f"{k} {v}" for k, v in c["rejected"].items()),
        _separation_line(s["pose_separation"]),
        f"L = {s['characteristic_length_m']:.4f} m; sigma per averaged test: "
        f"{s['measurement_sigma_per_test']['translation_m'] * 1e6:.2f} um, "
        f"{s['measurement_sigma_per_test']['rotation_rad'] * 1e6:.2f} urad",
        f"log det M: design {s['design']['log_det']:.3f}, random zone design "
        f"{s['random_zone_design']['log_det']:.3f}",
        "",
        "predicted standard error of k (first order, kN m/rad and % of the prior)",
        f"{'joint':>5} {'k prior':>12} {'design':>12} {'%':>7} {'random':>12} {'%':>7} "
        f"{'ratio':>6}",
    ]
    for r in s["predicted_standard_errors"]:
        design, random = (sig(r[f"se_{k}_N_m_per_rad"] / 1e3, 4, zeros=True)
                          for k in ("design", "random"))
        lines.append(
            f"{r['joint']:>5} {k_kNm(r['k_prior_N_m_per_rad']):>12} "
            f"{design:>12} {r['se_design_percent']:>7.3f} "
            f"{random:>12} {r['se_random_percent']:>7.3f} "
            f"{r['random_over_design']:>6.2f}"
        )
    lines += _criterion_lines(s)
    lines += _flank_lines(s)
    lines += _model_lines(s)
    return "\n".join(lines) + "\n"


def _flank_lines(s: dict) -> list[str]:
    if "gear_flanks" not in s:
        return []
    f = s["gear_flanks"]
    where = "; ".join(f"test {i + 1}: joint(s) {', '.join(map(str, js))}"
                      for i, js in enumerate(f["joints_per_test"]) if js)
    keep = [v for v in f["preload_fraction_keeping_flanks"] if v is not None]
    lines = ["", f"gear flank changes between the reference and the loaded reading (gravity "
             f"model of the robot file): {f['changes']} in {f['tests_with_changes']} of "
             f"{len(f['joints_per_test'])} tests" + (f" ({where})" if where else "")]
    a = s.get("link_compliance_alias_percent")
    if a:
        lines.append(f"links {', '.join(map(str, a['links']))} with [fake_lab]'s assumed "
                     "compliances would move k of the joint-only fit by (%, k1..): design "
                     + " ".join("-" if v is None else f"{v:+.1f}" for v in a["design"])
                     + "; random zone design "
                     + " ".join("-" if v is None else f"{v:+.1f}"
                                for v in a["random_zone_design"]))
    if f["changes"] and keep:
        lines.append("a reference reading under a preload in the load's direction keeps every "
                     "joint on one flank: load cases' preload_fraction above "
                     f"{max(keep):.3f} (per test: "
                     + ", ".join("-" if v is None else f"{v:.3f}"
                                 for v in f["preload_fraction_keeping_flanks"]) + ")")
    return lines


def _model_lines(s: dict) -> list[str]:
    """The model class's parameters' predicted se (SI, with units) and the fixed ones."""
    if "model_class" not in s:
        return []
    from analysis.report.formatting import sig

    m = s["model_class"]
    lines = ["", f"model class {m['model']}: the se of k above are marginal over its "
             "parameters (its fit's); joint springs only, %: "
             + " ".join(f"{v:.3f}" for v in m["k_se_joints_only_percent"]),
             f"predicted standard error of its {len(m['parameters'])} kept parameter(s) "
             "(SI): design, random zone design"]
    for p in m["parameters"]:
        rnd = "-" if p["se_random"] is None else sig(p["se_random"], 3)
        lines.append(f"  {p['name']:<10} {sig(p['se_design'], 3):>10} {rnd:>10}  {p['unit']}")
    for f in m["fixed"]:
        lines.append(f"  fixed at 0: {f['parameters']} ({f['why']})")
    lines.append(f"q2 over the tests: std {np.degrees(m['q2_std_rad']):.2f} deg, range "
                 f"{np.degrees(m['q2_range_rad']):.2f} deg")
    lines.append(f"{m['distinct_equations']} distinct equations for "
                 f"{m['parameters_estimated']} parameters ({m['equations_with_a_pose_held_out']}"
                 " with a pose held out)")
    if m["warning"]:
        lines.append(f"WARNING: {m['warning']}")
    if m.get("tests_raised"):
        lines.append(f"NOTE: {m['tests_raised']['why']}")
    return lines


def _separation_line(sep: dict) -> str:
    closest = sep["closest_pair_deg"]
    return (f"poses at least {sep['min_deg']:g} deg apart in joint space ({sep['source']}); "
            + ("one pose" if closest is None else f"closest pair {closest:.2f} deg"))


def _criterion_lines(s: dict) -> list[str]:
    lines = []
    if "noise_model_per_row" in s:
        n = s["noise_model_per_row"]
        lines += ["", f"noise per test row: {n['translation_sigma_um']:.2f} um, "
                  f"{n['rotation_sigma_urad']:.2f} urad, F/T {n['force_sigma_N']:.3g} N + "
                  f"{n['force_relative_percent']:.3g} % of |f|, {n['moment_sigma_Nm']:.3g} N m + "
                  f"{n['moment_relative_percent']:.3g} % of |m|, encoders "
                  f"{np.radians(n['joint_sigma_deg']) * 1e6:.3g} urad (every source in the "
                  "predictions)"]
        if s["noise_defaults_used"]:
            lines.append("not declared in the protocol, defaults used: "
                         + "; ".join(s["noise_defaults_used"]))
    if "worst_joint" in s:
        w = s["worst_joint"]
        lines.append(
            f"worst joint: k{w['joint_design']} at {w['design_percent']:.3f} % (design) vs "
            f"k{w['joint_random']} at {w['random_median_percent']:.3f} % (median of 201 random "
            f"zone designs): {w['reduction_percent']:.0f} % lower")
    for c in s.get("load_case_contributions", []):
        if not c["tests"]:
            lines.append(f"load case {c['load_case']}: not used")
            continue
        worst = max(c["relative_se_without"])
        lines.append(
            f"load case {c['load_case']}: {c['tests']} test(s); without them the worst "
            "relative se would be " + ("unbounded (a joint not identifiable)" if worst == np.inf
                                       else f"{100 * worst:.3f} %"))
    return lines


def write_plan(plan: Plan, out: str | Path, figure: bool = True) -> Path:
    """Write the plan directory ``out`` (created if needed); returns the plan.csv path."""
    from analysis.output_files import make_dir, write_text
    from campaign.protocol_copy import copy_beside, portable_copy

    out = make_dir(out)
    suffix = Path(plan.protocol.path).suffix.lower() or ".toml"
    for old in out.glob("protocol.*"):
        if old.suffix in (".toml", ".yaml", ".yml") and old.suffix != suffix:
            old.unlink()
    text, robot_files = portable_copy(plan.protocol)  # its robot file beside the copy
    write_text(out / f"protocol{suffix}", text)
    copy_beside(robot_files, out)
    csv_path = out / PLAN_FILE
    write_text(csv_path, format_frame(plan.to_frame()))
    write_text(out / "summary.txt", summary_text(plan))
    write_text(out / "summary.json",
               json.dumps(summary_dict(plan), indent=2, sort_keys=True) + "\n")
    if figure:
        from campaign.planning.plan_map import draw_plan_map

        draw_plan_map(plan, out / "plan_map.png")
    return csv_path


#: most repeats of one test a plan may ask for (a plan above it is refused, not run for days)
MAX_REPEATS = 1000


def read_plan(directory: str | Path) -> tuple[Protocol, pd.DataFrame]:
    """Read a plan directory written by :func:`write_plan`: (protocol, plan table).

    The table has the columns :data:`COLUMNS`: angles in degrees
    (``q*_model_deg`` model convention, ``q*_ctrl_deg`` controller convention),
    wrench components in N and N m in the robot base frame, ``v_r_deg`` in deg.
    ``test`` and ``repeats`` are whole numbers (1 <= repeats <= :data:`MAX_REPEATS`),
    the angles and wrench finite numbers; test ids are unique.

    Raises
    ------
    InputError
        No protocol copy, a plan that is not UTF-8 CSV text, a missing column, or
        a bad cell (the message names the line and column).
    """
    protocol, df, _ = load_plan(directory)
    return protocol, df


def load_plan(directory: str | Path) -> tuple[Protocol, pd.DataFrame, str]:
    """:func:`read_plan` and the verbatim text of ``plan.csv`` (hashed into a run)."""
    import io

    from analysis.file_errors import read_utf8

    directory = Path(directory)
    if not directory.is_dir():
        raise InputError("the plan directory does not exist (write one with campaign plan)"
                         if not directory.exists() else
                         "not a directory: --plan takes the directory campaign plan wrote",
                         where=str(directory))
    copies = sorted(p for p in directory.glob("protocol.*")
                    if p.suffix in (".toml", ".yaml", ".yml"))
    if not copies:
        raise InputError("no protocol.toml/.yaml in the plan directory", where=str(directory))
    protocol = load_protocol(copies[0])
    path = directory / PLAN_FILE
    text = read_utf8(path, "plan")
    if not text.strip():
        raise InputError("empty file: no header and no tests", where=str(path))
    try:
        df = pd.read_csv(io.StringIO(text), keep_default_na=False,
                         dtype={"zone": str, "load_case": str, "method": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as err:
        raise InputError(f"not a CSV table: {str(err).strip()}", where=str(path)) from None
    df.columns = [str(c).strip() for c in df.columns]
    missing = [c for c in COLUMNS if c not in df.columns]
    if missing:
        raise InputError(f"plan table lacks columns {missing}", where=str(path))
    if df.empty:
        raise InputError("the plan has no tests (a header only)", where=str(path))
    df = df.reset_index(drop=True)
    lines = np.arange(len(df)) + 2  # file line of each row (header = 1)
    # the planner's figures of merit (inv_kappa_F, v_p, v_r_deg) are information only
    for col in COLUMNS[COLUMNS.index("repeats") + 1:COLUMNS.index("inv_kappa_F")]:
        df[col] = _numbers(df, col, lines, path)
    for col in ("test", "repeats"):
        df[col] = _numbers(df, col, lines, path)
    for col, low, high in (("test", 0, 2**53), ("repeats", 1, MAX_REPEATS)):
        values = df[col].to_numpy()
        for bad, what in ((values != np.round(values), "is not a whole number"),
                          ((values < low) | (values > high), f"is outside {low}..{high}")):
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise InputError(f"line {lines[i]}, column {col}: {values[i]:g} {what}",
                                 where=str(path))
        df[col] = values.astype(np.int64)
    seen: dict[int, int] = {}
    for test, line in zip(df["test"], lines, strict=True):
        if test in seen:
            raise InputError(f"line {line}, column test: test {test} already on line "
                             f"{seen[test]} (test ids must be unique)", where=str(path))
        seen[test] = line
    return protocol, df, text


def _numbers(df: pd.DataFrame, col: str, lines: np.ndarray, path: Path) -> np.ndarray:
    """Column ``col`` as finite floats; an :class:`InputError` names the first bad cell."""
    raw = df[col].astype(str).str.strip().where(df[col].notna(), "")
    values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        what = "empty" if raw.iloc[i] == "" else f"{raw.iloc[i]!r} is not a finite number"
        raise InputError(f"line {lines[i]}, column {col}: {what}", where=str(path))
    return values
