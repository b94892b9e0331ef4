"""``campaign analyze``: identify the joint stiffness of a run (or a CSV file) and report it.

``campaign analyze RUN_DIR`` reads a run directory (``docs/run_format.md``),
``campaign analyze --measurements FILE.csv --robot R --out DIR`` imported
tests. Both write ``results.json``, ``residuals.csv`` (and ``validation.csv``)
and, unless ``--no-report``, ``report.html`` and ``report.pdf``.
"""

from __future__ import annotations

import atexit
import gc
import json
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import typer
from rich.console import Console
from rich.table import Table as RichTable

from analysis.errors import InputError
from analysis.identification.noise import NoiseModel
from campaign.cli_common import (
    PANEL_NOISE,
    PANEL_OUTPUT,
    Covariance,
    Method,
    Robust,
    echo,
    print_json,
    print_wrapped,
    stage,
)
from campaign.options import (
    TOOL_RPY_HELP,
    TOOL_XYZ_HELP,
    ToolPoint,
    file_tool_point,
    parse_floats,
    robot_and_tool,
    tool_option,
)
from campaign.run_noise import noise_from_protocol, protocol_noise_source

# Kept in step with analysis.identification.estimate (not imported here: every CLI command
# module is imported at start-up, and the identification pulls in scipy).
METHODS = ("ols", "wls", "exact")
DEFAULT_METHOD = "exact"
DEFAULT_TRIALS = 200

#: panels of --help (campaign.cli_common)
_INPUT = "Input and tool point"
_FIT = "Estimation and checks"
_REPORT = "Report"


# kept importable from here (tests and older scripts import it from this module)
_noise_from_protocol = noise_from_protocol


def _override_noise(noise: NoiseModel, t_um, r_urad, f_n, m_nm, q_urad=None, f_pct=None,
                    m_pct=None) -> tuple[NoiseModel, list]:
    """Apply the command line's *-sigma-* overrides (um, urad, N, N m, urad, %) to ``noise``.

    Returns the noise model and the options that changed it.
    """
    values, used = {}, []
    for key, value, scale, option in (
        ("translation_sigma_override", t_um, 1e-6, "--translation-sigma-um"),
        ("rotation_sigma_override", r_urad, 1e-6, "--rotation-sigma-urad"),
        ("force_sigma", f_n, 1.0, "--force-sigma-N"),
        ("moment_sigma", m_nm, 1.0, "--moment-sigma-Nm"),
        ("joint_sigma_override", q_urad, 1e-6, "--joint-sigma-urad"),
        ("force_relative", f_pct, 0.01, "--force-pct"),
        ("moment_relative", m_pct, 0.01, "--moment-pct"),
    ):
        if value is None:
            continue
        if not (np.isfinite(value) and (value > 0 or (value == 0 and option.endswith("pct")))):
            raise InputError("expected a positive number", where=option)
        values[key] = value * scale
        used.append(option)
    return (noise.with_overrides(**values) if values else noise), used


def _alias(value, old, name: str):
    """The value of a renamed option given by its new or its hidden old name."""
    if value is not None and old is not None:
        raise InputError("given twice (old and new name)", where=name)
    return value if value is not None else old


def _instrument_text(spec) -> str:
    if not isinstance(spec, dict):
        return str(spec)
    keys = ("driver", "address", "serial", "firmware", "unit", "units", "frame")
    return ", ".join(f"{k} {spec[k]}" if k != "driver" else str(spec[k])
                     for k in keys if spec.get(k) not in (None, ""))


def _run_info(run, robot_name: str, protocol, tool: ToolPoint):
    from analysis.report.summary import CampaignInfo
    from campaign.report_trace import run_trace

    meta = run.metadata
    tool = tool.text()
    if protocol is not None:
        tool += f", {protocol.tool.mass_kg:g} kg"
    flagged = []
    for _, r in run.flagged().iterrows():
        flagged.append({"test_id": r["test_id"], "repeat": r["repeat"], "pose": r["pose"],
                        "status": r["status"], "flags": r["flag_list"],
                        **{c: r[c] for c in ("repeatability_mm", "drift_mm", "wrench_error_N",
                                             "tracker_sigma_mm")},
                        "line": int(r["line"])})
    return CampaignInfo(
        source="run", location=str(run.path), robot=robot_name,
        tool=str(tool) if tool else "-",
        instruments={k: _instrument_text(v) for k, v in (meta.get("instruments") or {}).items()},
        started_utc=str(meta.get("started_utc") or "-"), ended_utc=str(meta.get("ended_utc")
                                                                       or "-"),
        operator=str(meta.get("operator") or "-"), status=run.status, reason=run.reason,
        protocol_file=str(meta.get("protocol_file") or run.protocol_path or "-"),
        protocol_sha256=run.protocol_sha256 or str(meta.get("protocol_sha256") or "-"),
        software={str(k): str(v) for k, v in (meta.get("software") or {}).items()},
        n_planned=run.n_planned, n_rows=len(run.tests), n_ok=len(run.ok),
        n_failed=run.n_failed, flagged=flagged, flag_counts=run.flag_counts(),
        notes=list(run.notes), **run_trace(run, protocol),
    )


def _tool_problem(result, model, tests, noise, method: str, tool) -> list[str]:
    """The tool-point F-test (:mod:`analysis.identification.tool_check`) as a refusal, if any.

    Stored in ``assumptions.tool_point.check``; refused at P < 1e-3 when P was assumed
    (no tool point given anywhere), at P < 1e-6 when one was given; a warning below 0.01.
    """
    from analysis.identification import tool_check

    if len(result.joints) < 6:
        # joints taken rigid leave a misfit of their own (the wrist absorbed by k1..k3), which
        # the offset columns would partly explain: the test would accuse a right tool
        result.assumptions.setdefault("tool_point", {})["check"] = {
            "skipped": "not all six joints identified: the rigid joints' own misfit would "
                       "show as a tool offset"}
        return []
    # the tests analysed (TestArrays: the text table is let go by then); the check takes
    # its own evenly spaced subset of a large campaign
    check = tool_check.tool_point_check(model, tests, result.joints, result.x, noise, method)
    if check is None:
        return []
    result.assumptions.setdefault("tool_point", {})["check"] = check.describe()
    assumed = tool.source.startswith("none given")
    limit = tool_check.P_ASSUMED if assumed else tool_check.P_GIVEN
    if check.p_value < limit:
        from analysis.report.formatting import k_kNm

        k = ", ".join("-" if not np.isfinite(v) else k_kNm(v) for v in check.k_moved)
        if assumed:
            return [f"a missing tool point: no tool point was given, P was taken at the flange "
                    f"centre, and {check.text()}; with P there k would be about [{k}] kN m/rad. "
                    "Give --tool-xyz-mm/--tool-rpy-deg (--tool-xyz-mm 0,0,0 if P really is "
                    "the flange centre)"]
        return [f"wrong tool point? {check.text()}; with P there k would be about [{k}] kN m/rad. "
                f"Check the tool point ({tool.source})"]
    if check.p_value < tool_check.P_WARN:
        result.warnings.append(f"tool point: {check.text()} (not significant enough to refuse)")
    return []


def _from_run(run_dir: Path, tool_xyz: str | None, tool_rpy: str | None):
    """(table, robot, noise, info, extras) of a run directory.

    extras: protocol, true_k, tool (:class:`ToolPoint`), noise_source, robot_source.
    """
    from campaign.protocol import load_protocol
    from campaign.protocol_robot import protocol_robot
    from campaign.run_reader import read_run
    from campaign.tests_meta import read_sidecar

    run = read_run(run_dir)
    protocol = load_protocol(run.protocol_path) if run.protocol_path else None
    if protocol is not None:
        t = protocol.tool
        tool = tool_option(tool_xyz, tool_rpy, ToolPoint(
            tuple(t.xyz_mm), tuple(t.rpy_deg), f"protocol [tool] ({Path(protocol.path).name})"))
        robot = protocol_robot(protocol, (np.asarray(tool.xyz_mm) * 1e-3,
                                          np.radians(tool.rpy_deg)))
        if tool.is_flange:  # the robot file's own [tool] (e.g. a model.toml), if any
            tool = file_tool_point(robot) or tool
        noise, noise_source = noise_from_protocol(protocol), protocol_noise_source(protocol)
        robot_source = f"protocol {Path(protocol.path).name} [campaign] robot"
    else:
        key = (run.metadata.get("robot") or {}).get("key")
        if not key:
            raise InputError("no protocol copy and no robot.key in the metadata: cannot tell "
                             "the robot", where=str(run.path / "metadata.json"))
        meta = read_sidecar(run.path / "tests.csv")
        robot, tool = robot_and_tool(str(key), None, tool_xyz, tool_rpy,
                                     meta.tool if meta else None)
        noise, noise_source = NoiseModel(), "defaults of analysis/identification/noise.py"
        if meta is not None and meta.noise is not None:
            noise, noise_source = meta.noise, meta.noise_source
        robot_source = "run metadata robot.key"
        deleted = (" (metadata.json records its protocol_sha256: it was deleted)"
                   if run.metadata.get("protocol_sha256") else "")
        run.notes.append(f"WARNING: no protocol copy in the run{deleted}: robot from the "
                         f"metadata robot.key {key!r}, tool {tool.source}, noise from "
                         f"{noise_source}; restore the protocol copy to analyse with its "
                         "figures")
    for note in run.notes:  # the loud ones also go to the terminal
        if note.startswith("WARNING"):
            echo(note, err=True)
    info = _run_info(run, robot.name, protocol, tool)
    true_k = (run.metadata.get("fake_lab") or {}).get("true_joint_stiffness")
    extras = {"protocol": protocol, "true_k": None if true_k is None else np.asarray(true_k,
                                                                                      float),
              "tool": tool, "noise_source": noise_source, "robot_source": robot_source}
    return run.ok, robot, noise, info, extras


def _sha256(path: Path) -> str:
    """SHA-256 of a file read in 1 MB chunks (a 1e6-row CSV is ~150 MB)."""
    import hashlib

    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _from_csv(path: Path, robot_spec: str | None, tip: str | None, tool_xyz: str | None,
              tool_rpy: str | None):
    """(tests, robot, noise, info, extras) of a tests CSV file and its sidecar, if any;
    tests as :class:`TestArrays` (read straight into arrays: a 1e6-row file never
    becomes a table)."""
    from analysis.identification.measurements import read_test_arrays
    from analysis.report.summary import CampaignInfo
    from campaign.tests_meta import read_sidecar

    meta = read_sidecar(path)
    notes = []
    if meta is not None:
        notes.append(f"sidecar {meta.path.name} read: tool, noise figures and robot from it "
                     "unless given on the command line")
    if robot_spec:
        robot_source = "--robot"
        if meta is not None and meta.robot_key and str(meta.robot_key).lower() != \
                robot_spec.strip().lower():
            robot_source += f" (the sidecar names {meta.robot_key!r})"
    elif meta is not None and meta.robot_key:
        robot_spec, robot_source = str(meta.robot_key), f"sidecar {meta.path.name}"
    else:
        raise InputError("--measurements needs --robot (built-in name, robot file or URDF); "
                         "no sidecar names it", where="--robot")
    tests = read_test_arrays(path)
    robot, tool = robot_and_tool(robot_spec, tip, tool_xyz, tool_rpy,
                                 meta.tool if meta else None)
    noise, noise_source = NoiseModel(), "defaults of analysis/identification/noise.py " \
        "(no sidecar)"
    if meta is not None and meta.noise is not None:
        noise, noise_source = meta.noise, meta.noise_source
    info = CampaignInfo(source="csv", location=str(path), robot=robot.name, tool=tool.text(),
                        protocol_file="-", protocol_sha256="-",
                        measurements_sha256=_sha256(path),
                        n_rows=tests.m, n_ok=tests.m, notes=notes)
    return tests, robot, noise, info, {"protocol": None, "true_k": None, "tool": tool,
                                       "noise_source": noise_source,
                                       "robot_source": robot_source}


METHOD_TEXT = {
    "ols": "ols: unweighted least squares on the linear model (the paper's eqs. 16-21)",
    "wls": "wls: linear model weighted by the measurement covariance",
    "exact": "exact: weighted Gauss-Newton on the nonlinear equilibrium",
}


def _assumptions(model, extras: dict, noise: NoiseModel, noise_source: str, method: str,
                 covariance: str, joints, robust: str = "none") -> dict:
    """What the analysis rests on (results.json ``assumptions``, the terminal, the report)."""
    from analysis.identification.poses import POSE_TOLERANCE_SIGMAS, pose_tolerance
    from campaign.tests_meta import CONVENTIONS

    tool: ToolPoint = extras["tool"]
    return {
        "robot": f"{model.name} ({extras['robot_source']})",
        "tool_point": tool.describe(),
        "noise": {**noise.describe(), "source": noise_source},
        "method": METHOD_TEXT.get(method, method),
        "covariance": ("model: the noise figures are taken as known" if covariance == "model"
                       else "residual: scaled by the reduced chi-square"),
        "robust": ("none: the Gaussian fit" if robust == "none" else
                   f"{robust} IRLS on the residuals whitened by the noise model's sigma "
                   "(scale 1: the noise figures are taken as known)"),
        "joints": ("all six, or 1-3 when no rotation is measured" if joints is None
                   else ", ".join(str(j + 1) for j in joints) + " (others rigid)"),
        "wrench_errors_in_variables": ("bias of the F/T noise in the regressor, "
                                       "~(sigma_w/|w|)^2, corrected with the figures above"),
        "poses": (f"tests whose joint angles agree to within "
                  f"{np.degrees(pose_tolerance(noise)):.2g} deg ({POSE_TOLERANCE_SIGMAS:g} "
                  "encoder sigmas) are at one pose"),
        "validation_folds": _folds_text(extras.get("protocol")),
        "conventions": CONVENTIONS,
    }


def _release_freed_heap() -> None:
    """:func:`analysis.identification.per_test.release_freed_heap` (the text table's cells
    are many small allocations: freed, they stay in the process, ~0.15 GB after a
    1e6-row import, under the arrays the fits then allocate)."""
    from analysis.identification.per_test import release_freed_heap

    release_freed_heap()


def _holdout_deg(protocol) -> tuple[float, str]:
    """Poses closer than this (deg) are held out together, and where that comes from."""
    from analysis.identification.holdout_check import CLUSTER_DEG

    if protocol is not None:
        return (float(protocol.thresholds.min_pose_separation_deg),
                f"protocol {Path(protocol.path).name} [thresholds] min_pose_separation_deg")
    return CLUSTER_DEG, "default, the planner's default minimum pose separation"


def _folds_text(protocol) -> str:
    deg, source = _holdout_deg(protocol)
    return (f"held-out validation: poses within {deg:g} deg of each other (joint space) are "
            f"held out together ({source})")


def _print_assumptions(console: Console, a: dict) -> None:
    n, t = a["noise"], a["tool_point"]
    console.print("[bold]Assumptions[/bold]")
    for line in (
        f"  robot: {a['robot']}",
        f"  tool point P: xyz {t['xyz_mm']} mm, rpy {t['rpy_deg']} deg in the flange frame "
        f"({t['source']})",
        f"  noise per test row: translation {n['translation_sigma_um']:.3g} um, rotation "
        f"{n['rotation_sigma_urad']:.3g} urad, force {n['force_sigma_N']:.3g} N + "
        f"{n['force_relative_percent']:.3g} % of |f|, moment {n['moment_sigma_Nm']:.3g} N m + "
        f"{n['moment_relative_percent']:.3g} % of |m|, encoders "
        f"{np.radians(n['joint_sigma_deg']) * 1e6:.3g} urad ({n['source']})",
        f"  method: {a['method']}; covariance {a['covariance']}; joints {a['joints']}",
        f"  robust fitting: {a['robust']}",
        f"  wrench errors in variables: {a['wrench_errors_in_variables']}",
        f"  poses: {a['poses']}",
        f"  {a['validation_folds']}",
    ):
        print_wrapped(console, line)


def _poses(robot, protocol, pose_args: list[str], q_tests: np.ndarray, labels) -> list:
    poses = []
    if protocol is not None:
        for name, deg in protocol.report.poses_deg.items():
            poses.append((name, np.radians(np.asarray(deg, float))))
    for i, text in enumerate(pose_args, start=1):
        poses.append((f"pose {i} (command line)",
                      np.radians(parse_floats(text, f"--pose #{i}", robot.n))))
    if not poses:
        poses.append((f"{labels[0]} (first tested pose)", q_tests[0]))
    for label, q in poses:
        if np.any(q < robot.lower - 1e-9) or np.any(q > robot.upper + 1e-9):
            raise InputError(f"{np.round(np.degrees(q), 3).tolist()} deg is outside the joint "
                             f"limits of {robot.name}", where=f"pose {label}")
    return poses


def _wrench(protocol, text: str | None, w_tests: np.ndarray,
            noise: NoiseModel) -> tuple[np.ndarray, str]:
    if text is not None:
        return parse_floats(text, "--wrench", 6), "--wrench"
    if protocol is not None and protocol.report.wrench is not None:
        return np.asarray(protocol.report.wrench, float), "protocol [report] wrench"
    from analysis.report.quantities import load_cases

    if protocol is not None:
        from analysis.report.test_table import match_load_cases

        cases = _load_cases(protocol, w_tests, noise)
        used = sorted(set(match_load_cases(w_tests, cases, noise.force_sigma,
                                           noise.moment_sigma).tolist()) - {-1})
        i = used[0] if used else 0
        return protocol.wrenches()[i], (
            f"load case '{protocol.load_cases[i].name}', the first one tested" if used else
            f"first load case '{protocol.load_cases[0].name}' (no test matches a load case)")

    # not the first test's measured wrench: its noise would show as a load component
    w, n = load_cases(w_tests, noise.force_sigma, noise.moment_sigma)[0]
    return w, (f"load case 1 of the imported tests: mean of its {n} measured wrench(es) "
               f"rounded to the noise sigmas ({noise.force_sigma:g} N, "
               f"{noise.moment_sigma:g} N m); --wrench to choose another")


def _load_cases(protocol, w_tests: np.ndarray, noise: NoiseModel) -> list:
    """The planned load cases (protocol), or those of the imported tests (CSV)."""
    from analysis.report.test_table import LoadCase

    if protocol is not None:
        return [LoadCase(c.name, c.method, w) for c, w in zip(protocol.load_cases,
                                                              protocol.wrenches(), strict=True)]
    from analysis.report.quantities import load_cases

    return [LoadCase(f"load case {i + 1}", "as measured", w) for i, (w, _) in
            enumerate(load_cases(w_tests, noise.force_sigma, noise.moment_sigma))]


def _map_fixed(protocol, n: int, q_poses: np.ndarray):
    """The maps' fixed joints: the plan map's rule (protocol fixed_deg, else the poses' median)."""
    from analysis.kinetostatics.map_fixed import map_fixed_joints

    return map_fixed_joints(n, None if protocol is None else protocol.sampling.fixed_deg,
                            q_poses)


@contextmanager
def _frozen_heap():
    """Leave the objects alive now (mostly those of the imported modules: numpy, pandas,
    matplotlib, fpdf, about a million) out of the cyclic garbage collector's passes until
    the block ends; objects made inside are collected as usual. Each full collection
    would otherwise walk all of them again, about 0.1 s each and several per report."""
    gc.freeze()
    try:
        yield
        # Every output is written and closed: at interpreter exit, the objects alive then
        # are left to the operating system instead of being walked by the final collection
        # and torn down one by one (about 0.4 s for this process). The other exit handlers
        # still run and stdout/stderr are still flushed; __del__ is never promised at exit.
        atexit.unregister(gc.freeze)
        atexit.register(gc.freeze)
    finally:
        gc.unfreeze()


def _print(console: Console, result, paths: dict, printed: int = 0) -> None:
    """The result's table, warnings (but the first ``printed``, on the terminal already)
    and files."""
    from analysis.report.formatting import interval_kNm, k_kNm

    table = RichTable(title=f"{result.robot}: identified joint stiffness ({result.method})")
    bias = result.linear_bias
    cols = ["joint", "k (kN m/rad)", f"{100 * result.confidence:g} % interval (kN m/rad)"]
    if bias is not None:  # ols/wls: the raw linear estimate beside the corrected one
        cols.append(f"raw {result.method}, linearisation bias not corrected (kN m/rad)")
    for col in cols:
        table.add_column(col, justify="right")
    for j in range(6):
        row = [f"k{j + 1}", k_kNm(result.k[j]), interval_kNm(*result.ci[j])
               if np.isfinite(result.k[j]) else "-"]
        if bias is not None:
            raw = bias["raw_joint_stiffness_Nm_per_rad"][j]
            row.append("-" if raw is None else k_kNm(raw))
        table.add_row(*row)
    console.print(table)
    for w in result.warnings[printed:]:
        print_wrapped(console, f"warning: {w}", style="yellow")
    for w in result.misfit_accepted:
        print_wrapped(console, f"ACCEPTED WITH --accept-misfit: {w}", style="red")
    for name, p in paths.items():
        print_wrapped(console, f"{name}: {p}")


def register(app: typer.Typer) -> None:
    @app.command("analyze")
    @_frozen_heap()
    def analyze(
        run_dir: Path = typer.Argument(None, help="Run directory written by campaign acquire."),
        measurements: Path = typer.Option(None, help="Tests CSV file (public import format).",
            rich_help_panel=_INPUT),
        robot: str = typer.Option(None, help="Robot of --measurements: built-in, file or URDF.",
            rich_help_panel=_INPUT),
        tip: str = typer.Option(None, help="Tool frame of a URDF.", rich_help_panel=_INPUT),
        out: Path = typer.Option(None, help="Output directory (default RUN_DIR/analysis).",
            rich_help_panel=PANEL_OUTPUT),
        method: Method = typer.Option(DEFAULT_METHOD, help="Estimator: ols (the paper's "
                                      "linear least squares), wls (weighted), exact "
                                      "(Gauss-Newton on the nonlinear equilibrium).",
            rich_help_panel=_FIT),
        joints: str = typer.Option(None, help="Joints to identify, e.g. 1,2,3 (others rigid).",
            rich_help_panel=_FIT),
        robust: Robust = typer.Option(
            "none", help="Robust fit for campaigns with glitches: none (the Gaussian fit), "
            "huber (c = 1.345) or tukey (c = 4.685) IRLS on the whitened residuals; the "
            "down-weighted rows are reported. Needs --method exact or wls.", rich_help_panel=_FIT),
        covariance: Covariance = typer.Option(
            "model", help="model (the noise figures are known) or residual (scaled by the "
            "reduced chi-square).", rich_help_panel=_FIT),
        pose: list[str] = typer.Option(  # noqa: B008 (typer's way of a repeatable option)
            [], help="Joint angles (deg, model convention) where K_X is reported; repeatable.",
            rich_help_panel=_REPORT),
        wrench: str = typer.Option(
            None, help="fx,fy,fz (N), mx,my,mz (N m) at P, base frame, for the predicted "
            "deflection (default: protocol [report] wrench or first load case).",
            rich_help_panel=_REPORT),
        trials: int = typer.Option(DEFAULT_TRIALS, help="Monte-Carlo trials per point of "
                                   "the robustness curve.", rich_help_panel=_REPORT),
        report: bool = typer.Option(True, "--report/--no-report", help="Write the report.",
            rich_help_panel=_REPORT),
        translation_sigma_um: float = typer.Option(
            None, "--translation-sigma-um",
            help="Override: sigma of one measured displacement component (um).",
            rich_help_panel=PANEL_NOISE),
        rotation_sigma_urad: float = typer.Option(
            None, "--rotation-sigma-urad",
            help="Override: sigma of one measured rotation component (urad).",
            rich_help_panel=PANEL_NOISE),
        old_translation: float = typer.Option(None, "--sigma-translation-um", hidden=True),
        old_rotation: float = typer.Option(None, "--sigma-rotation-urad", hidden=True),
        force_sigma_n: float = typer.Option(
            None, "--force-sigma-N", help="Override: sigma of a force component (N).",
            rich_help_panel=PANEL_NOISE),
        moment_sigma_nm: float = typer.Option(
            None, "--moment-sigma-Nm", help="Override: sigma of a moment component (N m).",
            rich_help_panel=PANEL_NOISE),
        joint_sigma_urad: float = typer.Option(
            None, help="Override: sigma of a joint angle reading, encoders (urad).",
            rich_help_panel=PANEL_NOISE),
        force_pct: float = typer.Option(
            None, "--force-pct", help="F/T force noise in % of |f| of the reading, in "
                                      "quadrature with --force-sigma-N.",
            rich_help_panel=PANEL_NOISE),
        moment_pct: float = typer.Option(
            None, "--moment-pct", help="F/T moment noise in % of |m| of the reading, in "
                                       "quadrature with --moment-sigma-Nm.",
            rich_help_panel=PANEL_NOISE),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP + " Overrides the "
                                        "protocol's or the sidecar's tool.",
            rich_help_panel=_INPUT),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP, rich_help_panel=_INPUT),
        accept_misfit: bool = typer.Option(
            False, "--accept-misfit", help="Write the result even when the checks refuse it "
            "(misfit, too good to be true, k > 10 x from nominal, negative k, a tool point the "
            "residuals contradict); results.json and the "
            "report then say so.", rich_help_panel=_FIT),
        as_json: bool = typer.Option(False, "--json", help="Print the result as JSON "
                                     "(the keys of results.json, SI units) instead of "
                                     "the tables.", rich_help_panel=PANEL_OUTPUT),
        force: bool = typer.Option(False, "--force", help="Replace a non-empty output "
                                   "directory: its contents as a whole, nothing of the "
                                   "earlier analysis is kept.", rich_help_panel=PANEL_OUTPUT),
    ) -> None:
        """Identify joint stiffness from a run or a CSV file; write results.json and the report.

        The measurement noise comes from the run's protocol (for a CSV file from
        its sidecar FILE.meta.json, else the instrument defaults of
        analysis/identification/noise.py); the --*-sigma-* options override it, per
        measured component of one test row. The tool point comes from the protocol
        (the sidecar; else the flange centre) unless --tool-xyz-mm/--tool-rpy-deg
        give it. A result the data do not support (misfit, too good, k more than
        10 x from the model's nominal, a negative k, a tool point the residuals
        contradict) is refused unless --accept-misfit. A non-empty output directory
        (an earlier analysis) is refused unless --force, which replaces it as a whole.
        """
        from analysis.identification.data_fingerprint import fingerprint
        from analysis.identification.estimate import identify, parse_joints
        from analysis.identification.measurements import TestArrays, to_arrays
        from analysis.identification.plausibility import problems
        from analysis.output_files import check_output_dir, replaced_dir

        gc.freeze()  # what was just imported joins the frozen objects (see _frozen_heap)
        method, covariance, robust = str(method), str(covariance), str(robust)
        translation_sigma_um = _alias(translation_sigma_um, old_translation,
                                      "--translation-sigma-um")
        rotation_sigma_urad = _alias(rotation_sigma_urad, old_rotation, "--rotation-sigma-urad")
        if (run_dir is None) == (measurements is None):
            raise InputError("give either RUN_DIR or --measurements FILE.csv --robot R",
                             where="campaign analyze")
        if run_dir is not None:
            if robot:
                raise InputError("a run names its robot in its protocol; drop --robot",
                                 where="--robot")
            check_output_dir(out or run_dir / "analysis", force, "--out",
                             replaces="replace its contents")
            table, model, noise, info, extras = _from_run(run_dir, tool_xyz_mm, tool_rpy_deg)
            out = out or run_dir / "analysis"
        else:
            if out is None:
                raise InputError("--measurements needs --out DIR", where="--out")
            check_output_dir(out, force, "--out", replaces="replace its contents")
            table, model, noise, info, extras = _from_csv(measurements, robot, tip,
                                                          tool_xyz_mm, tool_rpy_deg)
        protocol = extras["protocol"]
        noise, overridden = _override_noise(noise, translation_sigma_um, rotation_sigma_urad,
                                            force_sigma_n, moment_sigma_nm, joint_sigma_urad,
                                            force_pct, moment_pct)
        noise_source = extras["noise_source"] + (
            f"; overridden by {', '.join(overridden)}" if overridden else "")
        joint_list = parse_joints(joints)
        if report and trials < 10:
            raise InputError("need at least 10 trials", where="--trials")
        assumptions = _assumptions(model, extras, noise, noise_source, method, covariance,
                                   joint_list, robust)
        # with --json, stdout carries the JSON document only
        console = Console(stderr=as_json)
        _print_assumptions(console, assumptions)
        with stage(f"identification ({method}) and validation"):
            # the arrays once (a CSV file is read into them directly); the table of a run
            # is let go
            tests = table if isinstance(table, TestArrays) else to_arrays(table)
            del table
            _release_freed_heap()
            result = identify(model, tests, method=method, joints=joint_list,
                              noise=noise, covariance=covariance, robust=robust,
                              holdout_radius=np.radians(_holdout_deg(protocol)[0]))
        result.assumptions = assumptions
        # what the run's reader warned about (a damaged run) stays with the result
        early = [n.removeprefix("WARNING: ") for n in info.notes if n.startswith("WARNING")]
        result.warnings[:0] = early
        result.tests_data = fingerprint(tests)
        if measurements is not None and extras["tool"].source.startswith("none given"):
            result.warnings.insert(0, (
                "no tool point given: P assumed at the flange centre; if the displacements "
                "and wrench were measured at a tool point, give --tool-xyz-mm/--tool-rpy-deg "
                "(a tool error need not show in the chi-square, it shows in k)"))
        refused = problems(result, model.nominal_stiffness)
        _release_freed_heap()  # the identification's freed pages, before the checks
        # a linear fit whose bias was corrected is a compliance of the exact model: its
        # residuals are the exact model's (as in the chi-square)
        corrected = (result.linear_bias or {}).get("reliable", False)
        refused += _tool_problem(result, model, tests, noise,
                                 "exact" if corrected else method, extras["tool"])
        if refused and not accept_misfit:
            raise InputError(
                "refused, the data do not support this stiffness: " + " | ".join(refused)
                + "; to keep the result anyway rerun with --accept-misfit (results.json and "
                "the report then say so)", where=str(run_dir or measurements))
        result.misfit_accepted = refused
        _release_freed_heap()  # the identification's freed pages, before the writer's
        # everything is written into a new directory that replaces ``out`` as a whole at
        # the end: a refused or failed analysis leaves the earlier one untouched
        with replaced_dir(out, force, "--out") as new:
            paths = _write_outputs(result, model, new, tests, info, report, trials, protocol,
                                   wrench, noise, pose, extras, run_dir)
        paths = {k: out / Path(p).relative_to(new) for k, p in paths.items()}
        if as_json:
            summary = json.loads((out / "analysis.json").read_text())
            for w in result.warnings[len(early):]:  # still on the terminal, beside the JSON
                echo(f"warning: {w}", err=True)  # (the run's were printed on reading)
            print_json({**json.loads((out / "results.json").read_text()),
                        "files": {k: str(v) for k, v in paths.items()}, **summary})
            return
        _print(console, result, paths, printed=len(early))


def _write_outputs(result, model, out: Path, tests, info, report: bool, trials: int,
                   protocol, wrench, noise, pose, extras, run_dir) -> dict[str, Path]:
    """Write results.json, residuals.csv, model.toml, the report and analysis.json into
    ``out`` (a new directory); returns the paths of the main files by name."""
    from analysis.identification.result import write_results
    from analysis.output_files import write_text

    paths = write_results(result, out)
    from analysis.identification.model_export import export_model  # model.toml, K_X
    from analysis.report.traceability import stamp_results

    paths.update(export_model(result, model, out, tests, info))
    info.report_id = stamp_results(paths["results"], info.input_hashes())
    if report:
        # the report makes figures: matplotlib is imported only here
        from analysis.report.build import ReportInputs, build_report
        from analysis.report.write import write_report

        gc.freeze()
        labels = list(dict.fromkeys(tests.pose.tolist()))
        w, w_source = _wrench(protocol, wrench, tests.w, noise)
        if protocol is None:
            from analysis.report.build import wrench_text
            from analysis.report.quantities import load_cases

            info.wrenches = [(wrench_text(c), n) for c, n in
                             load_cases(tests.w, noise.force_sigma, noise.moment_sigma)]
        nominal, label = model.nominal_stiffness, "nominal (robot model)"
        nominal_source = (model.sources or {}).get(
            "stiffness", "the robot file's [stiffness] (its [sources] give no reference)")
        if nominal is None and protocol is not None and protocol.campaign.prior_stiffness:
            nominal, label = np.asarray(protocol.campaign.prior_stiffness), "prior (protocol)"
            nominal_source = f"protocol {Path(protocol.path).name} [campaign] " \
                "prior_stiffness"
        inputs = ReportInputs(
            robot=model, tests=tests, info=info, noise=noise, wrench=w,
            wrench_source=w_source, poses=_poses(model, protocol, pose, tests.q, labels),
            nominal=None if nominal is None else np.asarray(nominal, float),
            nominal_label=label, nominal_source=nominal_source, true_k=extras["true_k"],
            map_fixed=_map_fixed(protocol, model.n, tests.q[
                [int(np.flatnonzero(tests.pose == lab)[0]) for lab in labels]]),
            trials=trials, load_cases=_load_cases(protocol, tests.w, noise))
        with stage("report: maps, K_X, Monte-Carlo robustness, figures"):
            built = build_report(result, inputs)
        with stage("report: HTML and PDF"):
            paths.update(write_report(built, out))
    summary = {"run": str(run_dir) if run_dir else None, "partial": info.partial,
               "status": info.status, "failed_rows": info.n_failed}
    write_text(Path(out) / "analysis.json", json.dumps(summary, indent=2) + "\n")
    return paths
