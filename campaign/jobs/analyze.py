"""The ``analyze`` job: identify the joint stiffness of a run (or a CSV file) and report it.

Reads a run directory (``docs/run_format.md``) or imported tests (a CSV file and
its sidecar) into an :class:`~campaign.jobs.analyze_input.AnalysisInput`, applies the
noise overrides (:class:`~campaign.jobs.analyze_noise.NoiseOverrides`), identifies,
refuses what the data do not support
(:mod:`analysis.identification.checks.refusal_reasons`), and writes ``results.json``,
``residuals.csv``, ``validation.csv``, ``model.toml``, ``analysis.json`` and, unless
told not to, ``report.html`` and ``report.pdf`` into a new directory that replaces the
output directory as a whole. Messages name the command line's options
(``--translation-sigma-um``, ...): the web API answers with the same lines.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from analysis.errors import InputError, Refusal, Refused
from campaign.jobs import heap
from campaign.jobs.analyze_assumptions import assumptions, holdout_deg
from campaign.jobs.analyze_input import AnalysisInput, output_dir, read_input
from campaign.jobs.analyze_noise import NoiseOverrides
from campaign.jobs.choices import DEFAULT_METHOD, DEFAULT_TRIALS, Covariance, Method, Robust
from campaign.jobs.option_checks import Stage, no_stage, tool_texts

if TYPE_CHECKING:  # the identification imports scipy: not at start-up
    from analysis.identification.result import IdentificationResult


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
    fractions of |f| and |m|; None: the protocol's, the sidecar's or the defaults), flat
    fields (this record is also the web API's request body), read by the job as one
    record, ``noise_overrides``;
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

    @classmethod
    def with_noise(cls, noise: NoiseOverrides, **options) -> AnalyzeOptions:
        """The options ``options`` (fields by name) with the noise overrides ``noise``."""
        return cls(**options, **{f.name: getattr(noise, f.name)
                                 for f in fields(NoiseOverrides)})

    @property
    def noise_overrides(self) -> NoiseOverrides:
        """The noise overrides these options carry, as the record the job applies (SI)."""
        return NoiseOverrides(**{f.name: getattr(self, f.name)
                                 for f in fields(NoiseOverrides)})


@dataclass(frozen=True)
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


def run(o: AnalyzeOptions, stage: Stage = no_stage,
        on_assumptions: Callable[[dict], None] | None = None,
        warn: Callable[[str], None] | None = None) -> AnalyzeResult:
    """Read, identify, check and write; raise InputError on bad input or a refused result.

    ``on_assumptions(a)`` gets what the analysis rests on before the identification
    starts, ``warn(line)`` the loud warnings of a damaged run as it is read.
    """
    with heap.frozen_heap(), heap.arrow_on_c_heap():
        return _run(o, stage, on_assumptions or (lambda a: None), warn or (lambda s: None))


def _run(o: AnalyzeOptions, stage: Stage, on_assumptions, warn) -> AnalyzeResult:
    from analysis.identification.estimate import identify, parse_joints
    from analysis.identification.io.data_fingerprint import fingerprint
    from analysis.identification.models.names import parse_model

    heap.freeze_imported()  # what was just imported (see heap.frozen_heap)
    method, covariance, robust = str(o.method), str(o.covariance), str(o.robust)
    run_dir = None if o.run_dir is None else Path(o.run_dir)
    measurements = None if o.measurements is None else Path(o.measurements)
    out = output_dir(run_dir, measurements, o.robot, None if o.out is None else Path(o.out),
                     o.force)
    inp = read_input(run_dir, measurements, o.robot, o.tip,
                     *tool_texts(o.tool_xyz_mm, o.tool_rpy_deg), warn)
    heap.release_freed_heap()  # a run's text table, let go once read into arrays
    noise, overridden = o.noise_overrides.applied(inp.noise)
    inp = replace(inp, noise=noise, noise_source=inp.noise_source + (
        f"; overridden by {', '.join(overridden)}" if overridden else ""))
    joint_list = parse_joints(o.joints)
    model_choice = parse_model(o.model)
    if o.report and o.trials < 10:
        raise InputError("need at least 10 trials", where="--trials")
    on_assumptions(said := assumptions(inp, method, covariance, joint_list, robust))
    radius = np.radians(holdout_deg(inp.protocol)[0])
    with stage(f"identification ({method}) and validation"):
        result = identify(inp.robot, inp.tests, method=method, joints=joint_list,
                          noise=noise, covariance=covariance, robust=robust,
                          holdout_radius=radius)
    early = [n.removeprefix("WARNING: ") for n in inp.info.notes if n.startswith("WARNING")]
    result = replace(result, assumptions=said, tests_data=fingerprint(inp.tests),
                     warnings=(*_no_tool_point(inp), *early, *result.warnings))
    # a linear fit whose bias was corrected is a compliance of the exact model: its
    # residuals are the exact model's (as in the chi-square)
    checked = "exact" if (result.linear_bias or {}).get("reliable", False) else method
    # ---- the model classes (analysis/identification/models): one call, one place ----
    if model_choice.auto or model_choice.extras:
        from analysis.identification.models.apply import classes_of, with_class

        with stage(f"model classes ({model_choice.name})"):
            result = with_class(result, classes_of(result, inp.robot, inp.tests, noise,
                                                   checked, model_choice, radius))
    # ---- end of the model classes ----
    result = _checked(result, inp, checked, o.accept_misfit, run_dir or measurements)
    if model_choice.auto or model_choice.extras:  # ---- model classes, after the checks ----
        from analysis.identification.models.apply import widened

        result = widened(result)
    heap.release_freed_heap()  # the identification's freed pages, before the writer's
    return _written(result, inp, out, o, run_dir, stage, warn, len(early))


def _no_tool_point(inp: AnalysisInput) -> list[str]:
    """The warning of imported tests with no tool point given anywhere."""
    if not inp.imported or not inp.tool.source.startswith("none given"):
        return []
    return ["no tool point given: P assumed at the flange centre; if the displacements "
            "and wrench were measured at a tool point, give --tool-xyz-mm/--tool-rpy-deg "
            "(a tool error need not show in the chi-square, it shows in k)"]


def _checked(result, inp: AnalysisInput, method: str, accept_misfit: bool, where: Path):
    """``result`` with its checks recorded; raises :class:`Refused` with the reasons the
    data do not support it, unless ``accept_misfit`` (the result then lists them)."""
    from analysis.identification.checks.refusal_reasons import refusal_reasons

    heap.release_freed_heap()  # the identification's freed pages, before the checks
    refused, result = refusal_reasons(result, inp.robot, inp.tests, inp.noise, method,
                                      inp.tool.source, release=heap.release_freed_heap)
    if refused and not accept_misfit:
        raise Refused(tuple(Refusal(text) for text in refused), where=str(where))
    return replace(result, misfit_accepted=tuple(refused))


def _written(result, inp: AnalysisInput, out: Path, o: AnalyzeOptions, run_dir, stage, warn,
             early: int) -> AnalyzeResult:
    """Write everything into a new directory that replaces ``out`` as a whole at the end (a
    refused or failed analysis leaves the earlier one untouched); record it in the ledger."""
    from analysis.output_files import replaced_dir
    from analysis.report.model_classes import model_class_blocks
    from campaign.jobs.analyze_outputs import write_outputs
    from campaign.jobs.history import configured_ledger, record_analysis, report_history

    db = configured_ledger(o.ledger)
    history = None if db is None else (
        lambda folder: report_history(folder, run_dir, db, o.robot_id))
    with replaced_dir(out, o.force, "--out") as new:
        paths = write_outputs(result, inp, new, report=o.report, trials=o.trials,
                              wrench_N_Nm=o.wrench_N_Nm, poses_rad=o.poses_rad,
                              run_dir=run_dir, stage=stage, history=history)
    paths = {k: out / Path(p).relative_to(new) for k, p in paths.items()}
    recorded = None if db is None else record_analysis(out, db, o.robot_id, warn)
    return AnalyzeResult(json.loads((out / "results.json").read_text()),
                         json.loads((out / "analysis.json").read_text()), paths, result,
                         early, result.assumptions, recorded,
                         tuple(model_class_blocks(result.assumptions.get("model_classes"))[:1]))
