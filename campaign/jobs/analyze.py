"""The ``analyze`` job: identify the joint stiffness of a run (or a CSV file) and report it.

Reads a run directory (``docs/run_format.md``) or imported tests (a CSV file and
its sidecar), applies the noise overrides, identifies, refuses what the data do
not support, and writes ``results.json``, ``residuals.csv``, ``validation.csv``,
``model.toml``, ``analysis.json`` and, unless told not to, ``report.html`` and
``report.pdf`` into a new directory that replaces the output directory as a whole.
Messages name the command line's options (``--translation-sigma-um``, ...): the
web API answers with the same lines.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from analysis.errors import InputError, Refusal, Refused
from analysis.identification.noise import NoiseModel
from campaign.jobs import heap
from campaign.jobs.choices import DEFAULT_METHOD, DEFAULT_TRIALS, Covariance, Method, Robust
from campaign.jobs.common import Stage, floats, no_stage, six_joints, tool_texts
from campaign.options import ToolPoint, file_tool_point, robot_and_tool, tool_option
from campaign.run_noise import noise_from_protocol, protocol_noise_source

if TYPE_CHECKING:  # the identification imports scipy: not at start-up
    from analysis.identification.result import IdentificationResult


@dataclass(frozen=True)
class NoiseOverride:
    """One noise figure an analysis may override: ``field`` of :class:`AnalyzeOptions` (SI),
    the :class:`NoiseModel` field it sets, the command-line ``option`` that gives it (named
    in messages), and ``to_si``: that option's unit in SI (um -> m: 1e-6; % -> 0.01)."""

    field: str
    noise_field: str
    option: str
    to_si: float


#: the noise overrides, each a record (the command line and the web name them, never
#: count them)
NOISE_OVERRIDES: tuple[NoiseOverride, ...] = (
    NoiseOverride("translation_sigma_m", "translation_sigma_override",
                  "--translation-sigma-um", 1e-6),
    NoiseOverride("rotation_sigma_rad", "rotation_sigma_override", "--rotation-sigma-urad",
                  1e-6),
    NoiseOverride("force_sigma_N", "force_sigma", "--force-sigma-N", 1.0),
    NoiseOverride("moment_sigma_Nm", "moment_sigma", "--moment-sigma-Nm", 1.0),
    NoiseOverride("joint_sigma_rad", "joint_sigma_override", "--joint-sigma-urad", 1e-6),
    NoiseOverride("force_relative", "force_relative", "--force-pct", 0.01),
    NoiseOverride("moment_relative", "moment_relative", "--moment-pct", 0.01),
)


def noise_fields(typed: dict[str, float | None]) -> dict[str, float | None]:
    """The options record's noise fields (SI; None: not given) from the values typed in the
    command line's units, by option (``{"--force-sigma-N": 2.0, "--force-pct": 0.5}``)."""
    unknown = set(typed) - {n.option for n in NOISE_OVERRIDES}
    if unknown:
        raise ValueError(f"not noise options: {', '.join(sorted(unknown))}")
    return {n.field: None if typed.get(n.option) is None else typed[n.option] * n.to_si
            for n in NOISE_OVERRIDES}


@dataclass(frozen=True)
class AnalyzeOptions:
    """What to analyse and how (SI units; noise figures per measured component of one row).

    run_dir: a run directory, or measurements: a tests CSV file with robot (built-in
    name, robot file or URDF; tip: its tool frame); out: the output directory (default
    RUN_DIR/analysis); method, robust, covariance: the estimator and its options;
    joints: joints to identify ("1,2,3" or [1, 2, 3], 1-based; others rigid);
    poses_rad: joint angles (rad, model convention) where K_X is reported;
    wrench_N_Nm: at P, base frame, for the predicted deflection; trials: Monte-Carlo
    trials per point of the report's robustness curve; report: write the report;
    translation_sigma_m .. moment_relative: noise overrides (m, rad, N, N m, rad, and
    fractions of |f| and |m|; None: the protocol's, the sidecar's or the defaults);
    tool_xyz_mm / tool_rpy_deg: the tool point as the protocol's [tool] gives it (mm,
    deg), overriding the protocol's or sidecar's; accept_misfit: write a refused result
    (it says so); force: replace a non-empty output directory as a whole; ledger: the
    fleet ledger's URL (None: the STIFFNESS_CAMPAIGN_DB environment variable; neither:
    nothing recorded), where the analysis is recorded and whose earlier campaigns of the
    robot make the report's history section; robot_id: the robot's identity in the
    ledger when the run names no serial."""

    run_dir: Path | None = None
    measurements: Path | None = None
    robot: str | None = None
    tip: str | None = None
    out: Path | None = None
    method: Method = Method(DEFAULT_METHOD)
    joints: str | Sequence[int] | None = None
    robust: Robust = Robust("none")
    covariance: Covariance = Covariance("model")
    poses_rad: Sequence[Sequence[float]] = ()
    wrench_N_Nm: Sequence[float] | None = None
    trials: int = DEFAULT_TRIALS
    report: bool = True
    translation_sigma_m: float | None = None
    rotation_sigma_rad: float | None = None
    force_sigma_N: float | None = None
    moment_sigma_Nm: float | None = None
    joint_sigma_rad: float | None = None
    force_relative: float | None = None
    moment_relative: float | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    accept_misfit: bool = False
    force: bool = False
    ledger: str | None = None
    robot_id: str | None = None
    model: str = "joints"


@dataclass
class AnalyzeResult:
    """results: results.json's document (SI units); summary: analysis.json's; files: the
    main files by name; identification: the identification result (k, ci, warnings, ...);
    early_warnings: how many of its warnings came from reading the run (already reported
    through the ``warn`` hook)."""

    results: dict
    summary: dict
    files: dict[str, Path]
    identification: IdentificationResult | None = None
    early_warnings: int = 0
    assumptions: dict = field(default_factory=dict)
    ledger: dict | None = None
    #: tables for the terminal beside the result's (the model classes side by side)
    tables: tuple = ()

    def to_json(self) -> dict:
        """The document ``campaign analyze --json`` prints."""
        out = {**self.results, "files": {k: str(v) for k, v in self.files.items()},
               **self.summary}
        if self.ledger is not None:
            out["ledger"] = self.ledger
        return out




def override_noise(noise: NoiseModel, values: dict[str, float | None]) -> tuple[NoiseModel, list]:
    """Apply the noise overrides ``values`` (options record field -> SI value, None: not
    given) to ``noise``; returns the noise model and the options (as the command line
    names them) that changed it."""
    changed, used = {}, []
    for n in NOISE_OVERRIDES:
        value = values.get(n.field)
        if value is None:
            continue
        if not (np.isfinite(value) and (value > 0 or (value == 0 and n.option.endswith("pct")))):
            raise InputError("expected a positive number", where=n.option)
        changed[n.noise_field] = value
        used.append(n.option)
    return (noise.with_overrides(**changed) if changed else noise), used


def _instrument_text(spec) -> str:
    if not isinstance(spec, dict):
        return str(spec)
    keys = ("driver", "address", "serial", "firmware", "unit", "units", "frame")
    return ", ".join(f"{k} {spec[k]}" if k != "driver" else str(spec[k])
                     for k in keys if spec.get(k) not in (None, ""))


def _run_info(run, robot_name: str, protocol, tool: ToolPoint):
    from analysis.report.summary import CampaignInfo
    from campaign.run_format.trace import run_trace

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
        operator=_operator_text(meta), status=run.status, reason=run.reason,
        protocol_file=str(meta.get("protocol_file") or run.protocol_path or "-"),
        protocol_sha256=run.protocol_sha256 or str(meta.get("protocol_sha256") or "-"),
        software={str(k): str(v) for k, v in (meta.get("software") or {}).items()},
        n_planned=run.n_planned, n_rows=len(run.tests), n_ok=len(run.ok),
        n_failed=run.n_failed, flagged=flagged, flag_counts=run.flag_counts(),
        notes=list(run.notes), **run_trace(run, protocol),
    )


def _tool_problem(result, model, tests, noise, method: str, tool):
    """(refusals, result): the tool-point F-test
    (:mod:`analysis.identification.checks.tool_check`) as a refusal, if any, and the result
    that records it.

    Stored in ``assumptions.tool_point.check``; refused at P < 1e-3 when P was assumed
    (no tool point given anywhere), at P < 1e-6 when one was given; a warning below 0.01.
    """
    from analysis.identification.checks import tool_check

    def checked(description: dict):
        tool_point = {**result.assumptions.get("tool_point", {}), "check": description}
        return replace(result, assumptions={**result.assumptions, "tool_point": tool_point})

    if len(result.joints) < 6:
        # joints taken rigid leave a misfit of their own (the wrist absorbed by k1..k3), which
        # the offset columns would partly explain: the test would accuse a right tool
        return [], checked({
            "skipped": "not all six joints identified: the rigid joints' own misfit would "
                       "show as a tool offset"})
    # the tests analysed (TestArrays: the text table is let go by then); the check takes
    # its own evenly spaced subset of a large campaign
    check = tool_check.tool_point_check(model, tests, result.joints, result.x, noise, method)
    if check is None:
        return [], result
    result = checked(check.describe())
    assumed = tool.source.startswith("none given")
    limit = tool_check.P_ASSUMED if assumed else tool_check.P_GIVEN
    if check.p_value < limit:
        from analysis.report.formatting import k_kNm

        k = ", ".join("-" if not np.isfinite(v) else k_kNm(v) for v in check.k_moved)
        if assumed:
            return [f"a missing tool point: no tool point was given, P was taken at the flange "
                    f"centre, and {check.text()}; with P there k would be about [{k}] kN m/rad. "
                    "Give --tool-xyz-mm/--tool-rpy-deg (--tool-xyz-mm 0,0,0 if P really is "
                    "the flange centre)"], result
        return [f"wrong tool point? {check.text()}; with P there k would be about [{k}] kN m/rad. "
                f"Check the tool point ({tool.source})"], result
    if check.p_value < tool_check.P_WARN:
        result = replace(result, warnings=(
            *result.warnings, f"tool point: {check.text()} (not significant enough to refuse)"))
    return [], result


@dataclass(frozen=True)
class AnalysisInput:
    """What an analysis rests on besides its tests, read from a run directory or a tests
    CSV file: the robot model, the noise model of one test row and where its figures come
    from, the campaign's facts (:class:`analysis.report.summary.CampaignInfo`), the
    protocol (None for a CSV file), the simulated lab's true joint stiffness (N m/rad;
    None unless simulated), the tool point and where the robot comes from.

    The tests travel beside it (``(tests, input)``), so that a run's table can be let go
    once it is turned into arrays."""

    robot: Any
    noise: NoiseModel
    noise_source: str
    info: Any
    protocol: Any
    true_k: np.ndarray | None
    tool: ToolPoint
    robot_source: str


def _from_run(run_dir: Path, tool_xyz: str | None, tool_rpy: str | None,
              warn: Callable[[str], None]) -> tuple[Any, AnalysisInput]:
    """(the run's table of good rows, :class:`AnalysisInput`) of a run directory."""
    from campaign.protocol import load_protocol
    from campaign.protocol_robot import protocol_robot
    from campaign.run_format.reader import read_run
    from campaign.run_format.tests_meta import read_sidecar

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
            warn(note)
    info = _run_info(run, robot.name, protocol, tool)
    true_k = (run.metadata.get("fake_lab") or {}).get("true_joint_stiffness")
    return run.ok, AnalysisInput(robot, noise, noise_source, info, protocol,
                                 None if true_k is None else np.asarray(true_k, float),
                                 tool, robot_source)


def _sha256(path: Path) -> str:
    """SHA-256 of a file read in 1 MB chunks (a 1e6-row CSV is ~150 MB)."""
    import hashlib

    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _from_csv(path: Path, robot_spec: str | None, tip: str | None, tool_xyz: str | None,
              tool_rpy: str | None) -> tuple[Any, AnalysisInput]:
    """(tests, :class:`AnalysisInput`) of a tests CSV file and its sidecar, if any; tests
    as :class:`TestArrays` (read straight into arrays: a 1e6-row file never becomes a
    table)."""
    from analysis.identification.io.csv_reader import read_test_arrays
    from analysis.report.summary import CampaignInfo
    from campaign.run_format.tests_meta import read_sidecar

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
    six_joints(robot)  # before the assumptions are printed: the test format has 6 joints
    noise, noise_source = NoiseModel(), "defaults of analysis/identification/noise.py " \
        "(no sidecar)"
    if meta is not None and meta.noise is not None:
        noise, noise_source = meta.noise, meta.noise_source
    info = CampaignInfo(source="csv", location=str(path), robot=robot.name, tool=tool.text(),
                        protocol_file="-", protocol_sha256="-",
                        measurements_sha256=_sha256(path),
                        n_rows=tests.m, n_ok=tests.m, notes=notes)
    return tests, AnalysisInput(robot, noise, noise_source, info, None, None, tool,
                                robot_source)


METHOD_TEXT = {
    "ols": "ols: unweighted least squares on the linear model (the paper's eqs. 16-21)",
    "wls": "wls: linear model weighted by the measurement covariance",
    "exact": "exact: weighted Gauss-Newton on the nonlinear equilibrium",
}


def _assumptions(inp: AnalysisInput, noise: NoiseModel, noise_source: str, method: str,
                 covariance: str, joints, robust: str = "none") -> dict:
    """What the analysis rests on (results.json ``assumptions``, the terminal, the report);
    ``noise``, ``noise_source``: ``inp``'s with the options' overrides."""
    from analysis.identification.poses import POSE_TOLERANCE_SIGMAS, pose_tolerance
    from campaign.run_format.tests_meta import CONVENTIONS

    tool = inp.tool
    return {
        "robot": f"{inp.robot.name} ({inp.robot_source})",
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
        "validation_folds": _folds_text(inp.protocol),
        "conventions": CONVENTIONS,
    }


def _holdout_deg(protocol) -> tuple[float, str]:
    """Poses closer than this (deg) are held out together, and where that comes from."""
    from analysis.identification.validation.holdout_check import CLUSTER_DEG

    if protocol is not None:
        name = Path(protocol.path).name
        if "min_pose_separation_deg" in protocol.thresholds.model_fields_set:
            return (float(protocol.thresholds.min_pose_separation_deg),
                    f"protocol {name} [thresholds] min_pose_separation_deg")
        return (float(protocol.thresholds.min_pose_separation_deg),
                f"default: protocol {name} has no [thresholds] min_pose_separation_deg")
    return CLUSTER_DEG, "default, the planner's default minimum pose separation"


def _folds_text(protocol) -> str:
    deg, source = _holdout_deg(protocol)
    return (f"held-out validation: poses within {deg:g} deg of each other (joint space) are "
            f"held out together ({source})")


def _poses(robot, protocol, pose_args: Sequence[Sequence[float]], q_tests: np.ndarray,
           labels) -> list:
    poses = []
    if protocol is not None:
        for name, deg in protocol.report.poses_deg.items():
            poses.append((name, np.radians(np.asarray(deg, float))))
    for i, values in enumerate(pose_args, start=1):
        poses.append((f"pose {i} (command line)", floats(values, f"--pose #{i}", robot.n)))
    if not poses:
        poses.append((f"{labels[0]} (first tested pose)", q_tests[0]))
    for label, q in poses:
        if np.any(q < robot.lower - 1e-9) or np.any(q > robot.upper + 1e-9):
            raise InputError(f"{np.round(np.degrees(q), 3).tolist()} deg is outside the joint "
                             f"limits of {robot.name}", where=f"pose {label}")
    return poses


def _wrench(protocol, values: Sequence[float] | None, w_tests: np.ndarray,
            noise: NoiseModel) -> tuple[np.ndarray, str]:
    if values is not None:
        return floats(values, "--wrench", 6), "--wrench"
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


def _write_outputs(result, model, out: Path, tests, info, report: bool, trials: int,
                   protocol, wrench, noise, pose, true_k, run_dir,
                   stage: Stage = no_stage, history=None) -> dict[str, Path]:
    """Write results.json, residuals.csv, model.toml, the report and analysis.json into
    ``out`` (a new directory); returns the paths of the main files by name."""
    from analysis.identification.io.results_json import write_results
    from analysis.output_files import write_text

    paths = write_results(result, out)
    from analysis.identification.io.model_export import export_model  # model.toml, K_X
    from analysis.report.traceability import stamp_results

    paths.update(export_model(result, model, out, tests, info))
    info.report_id = stamp_results(paths["results"], info.input_hashes())
    if report:
        # the report makes figures: matplotlib is imported only here
        from analysis.report.build import ReportInputs, build_report
        from analysis.report.write import write_report

        heap.freeze_imported()
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
            nominal_label=label, nominal_source=nominal_source, true_k=true_k,
            map_fixed=_map_fixed(protocol, model.n, tests.q[
                [int(np.flatnonzero(tests.pose == lab)[0]) for lab in labels]]),
            trials=trials, load_cases=_load_cases(protocol, tests.w, noise),
            history=None if history is None else history(out))
        with stage("report: maps, K_X, Monte-Carlo robustness, figures"):
            built = build_report(result, inputs)
        with stage("report: HTML and PDF"):
            paths.update(write_report(built, out))
    summary = {"run": str(run_dir) if run_dir else None, "partial": info.partial,
               "status": info.status, "failed_rows": info.n_failed}
    write_text(Path(out) / "analysis.json", json.dumps(summary, indent=2) + "\n")
    return paths


def run(o: AnalyzeOptions, stage: Stage = no_stage,
        on_assumptions: Callable[[dict], None] | None = None,
        warn: Callable[[str], None] | None = None) -> AnalyzeResult:
    """Read, identify, check and write; raise InputError on bad input or a refused result.

    ``on_assumptions(a)`` gets what the analysis rests on before the identification
    starts, ``warn(line)`` the loud warnings of a damaged run as it is read.
    """
    with heap.frozen_heap():
        return _run(o, stage, on_assumptions or (lambda a: None), warn or (lambda s: None))


def _run(o: AnalyzeOptions, stage: Stage, on_assumptions, warn) -> AnalyzeResult:
    from analysis.identification.checks.misfit_causes import causes_of_misfit
    from analysis.identification.checks.plausibility import problems
    from analysis.identification.estimate import identify, parse_joints
    from analysis.identification.io.data_fingerprint import fingerprint
    from analysis.identification.io.measurements import TestArrays, to_arrays
    from analysis.output_files import check_output_dir, replaced_dir

    heap.freeze_imported()  # what was just imported (see heap.frozen_heap)
    method, covariance, robust = str(o.method), str(o.covariance), str(o.robust)
    run_dir = None if o.run_dir is None else Path(o.run_dir)
    measurements = None if o.measurements is None else Path(o.measurements)
    out = None if o.out is None else Path(o.out)
    tool_xyz_mm, tool_rpy_deg = tool_texts(o.tool_xyz_mm, o.tool_rpy_deg)
    if (run_dir is None) == (measurements is None):
        raise InputError("give either RUN_DIR or --measurements FILE.csv --robot R",
                         where="campaign analyze")
    if run_dir is not None:
        if o.robot:
            raise InputError("a run names its robot in its protocol; drop --robot",
                             where="--robot")
        check_output_dir(out or run_dir / "analysis", o.force, "--out",
                         replaces="replace its contents")
        table, inp = _from_run(run_dir, tool_xyz_mm, tool_rpy_deg, warn)
        out = out or run_dir / "analysis"
    else:
        if out is None:
            raise InputError("--measurements needs --out DIR", where="--out")
        check_output_dir(out, o.force, "--out", replaces="replace its contents")
        table, inp = _from_csv(measurements, o.robot, o.tip, tool_xyz_mm, tool_rpy_deg)
    model, info, protocol = inp.robot, inp.info, inp.protocol
    noise, overridden = override_noise(inp.noise, {n.field: getattr(o, n.field)
                                                   for n in NOISE_OVERRIDES})
    noise_source = inp.noise_source + (
        f"; overridden by {', '.join(overridden)}" if overridden else "")
    joint_list = parse_joints(o.joints)
    from analysis.identification.models.names import parse_model

    model_choice = parse_model(o.model)
    if o.report and o.trials < 10:
        raise InputError("need at least 10 trials", where="--trials")
    assumptions = _assumptions(inp, noise, noise_source, method, covariance, joint_list,
                               robust)
    on_assumptions(assumptions)
    with stage(f"identification ({method}) and validation"):
        # the arrays once (a CSV file is read into them directly); the table of a run
        # is let go
        tests = table if isinstance(table, TestArrays) else to_arrays(table)
        del table
        heap.release_freed_heap()
        result = identify(model, tests, method=method, joints=joint_list,
                          noise=noise, covariance=covariance, robust=robust,
                          holdout_radius=np.radians(_holdout_deg(protocol)[0]))
    # what the run's reader warned about (a damaged run) stays with the result
    early = [n.removeprefix("WARNING: ") for n in info.notes if n.startswith("WARNING")]
    no_tool = []
    if measurements is not None and inp.tool.source.startswith("none given"):
        no_tool = [
            "no tool point given: P assumed at the flange centre; if the displacements "
            "and wrench were measured at a tool point, give --tool-xyz-mm/--tool-rpy-deg "
            "(a tool error need not show in the chi-square, it shows in k)"]
    result = replace(result, assumptions=assumptions, tests_data=fingerprint(tests),
                     warnings=(*no_tool, *early, *result.warnings))
    # a linear fit whose bias was corrected is a compliance of the exact model: its
    # residuals are the exact model's (as in the chi-square)
    corrected = (result.linear_bias or {}).get("reliable", False)
    if model_choice.auto or model_choice.extras:
        from analysis.identification.models.apply import classes_of, with_class

        with stage(f"model classes ({model_choice.name})"):
            result = with_class(result, classes_of(
                result, model, tests, noise, "exact" if corrected else method, model_choice,
                np.radians(_holdout_deg(protocol)[0])))
    causes, result = causes_of_misfit(result, model, tests, noise,
                                      "exact" if corrected else method)
    refused = problems(result, model.nominal_stiffness, causes=causes)
    heap.release_freed_heap()  # the identification's freed pages, before the checks
    tool_refusals, result = _tool_problem(result, model, tests, noise,
                                          "exact" if corrected else method, inp.tool)
    refused += tool_refusals
    if refused and not o.accept_misfit:
        raise Refused(tuple(Refusal(text) for text in refused),
                      where=str(run_dir or measurements))
    result = replace(result, misfit_accepted=tuple(refused))
    if model_choice.auto or model_choice.extras:
        from analysis.identification.models.apply import widened

        result = widened(result)
    heap.release_freed_heap()  # the identification's freed pages, before the writer's
    # everything is written into a new directory that replaces ``out`` as a whole at
    # the end: a refused or failed analysis leaves the earlier one untouched
    from campaign.jobs.history import configured_ledger, report_history

    db = configured_ledger(o.ledger)
    history = None if db is None else (
        lambda folder: report_history(folder, run_dir, db, o.robot_id))
    with replaced_dir(out, o.force, "--out") as new:
        paths = _write_outputs(result, model, new, tests, info, o.report, o.trials, protocol,
                               o.wrench_N_Nm, noise, o.poses_rad, inp.true_k, run_dir, stage,
                               history)
    paths = {k: out / Path(p).relative_to(new) for k, p in paths.items()}
    recorded = None
    if db is not None:
        from campaign.jobs.history import record_analysis

        recorded = record_analysis(out, db, o.robot_id, warn)
    from analysis.report.model_classes import model_class_blocks

    return AnalyzeResult(json.loads((out / "results.json").read_text()),
                         json.loads((out / "analysis.json").read_text()), paths, result,
                         len(early), result.assumptions, recorded,
                         tuple(model_class_blocks(result.assumptions.get("model_classes"))[:1]))


def _operator_text(meta: dict) -> str:
    """The operator recorded in metadata.json, saying when it is only the OS login name (a
    run recorded without --operator; older runs do not say where the name came from)."""
    name = str(meta.get("operator") or "-")
    source = meta.get("operator_source")
    if name != "-" and source and source != "--operator":
        return f"{name} ({source})"
    return name
