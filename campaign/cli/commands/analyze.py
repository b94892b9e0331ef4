"""``campaign analyze``: identify the joint stiffness of a run (or a CSV file) and report it.

``campaign analyze RUN_DIR`` reads a run directory (``docs/run_format.md``),
``campaign analyze --measurements FILE.csv --robot R --out DIR`` imported
tests. Both write ``results.json``, ``residuals.csv`` (and ``validation.csv``)
and, unless ``--no-report``, ``report.html`` and ``report.pdf``. The work is
:mod:`campaign.jobs.analyze`; this module parses the options and presents.
"""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console
from rich.table import Table as RichTable

from analysis.errors import InputError
from campaign.cli.terminal import (
    DEFAULT_METHOD,
    DEFAULT_TRIALS,
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
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option

#: panels of --help (campaign.cli.terminal)
_INPUT = "Input and tool point"
_FIT = "Estimation and checks"
_REPORT = "Report"


def _alias(value, old, name: str):
    """The value of a renamed option given by its new or its hidden old name."""
    if value is not None and old is not None:
        raise InputError("given twice (old and new name)", where=name)
    return value if value is not None else old


def _print_assumptions(console: Console, a: dict) -> None:
    import numpy as np

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


def _print(console: Console, result, paths: dict, printed: int = 0,
           tables: tuple = (), ledger: dict | None = None) -> None:
    """The result's table, the job's extra ``tables``, warnings (but the first
    ``printed``, on the terminal already), files and where the fleet ``ledger`` (the
    job's record of it, None without one) keeps the analysis."""
    import numpy as np

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
    for block in tables:  # the job's extra tables (the model classes side by side)
        classes = RichTable(title=block.title)
        for col in block.columns:
            classes.add_column(col, justify="right")
        for row in block.rows:
            classes.add_row(*row)
        console.print(classes)
    for w in result.warnings[printed:]:
        print_wrapped(console, f"warning: {w}", style="yellow")
    for w in result.misfit_accepted:
        print_wrapped(console, f"ACCEPTED WITH --accept-misfit: {w}", style="red")
    for name, p in paths.items():
        print_wrapped(console, f"{name}: {p}")
    if ledger is not None and ledger.get("report_id"):
        verb = "recorded in" if ledger["added"] else "already in"
        echo(f"ledger: {verb} the fleet ledger as robot {ledger['robot']}")


def register(app: typer.Typer) -> None:
    @app.command("analyze")
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
            "down-weighted rows are reported. Around --method exact, wls or ols.",
            rich_help_panel=_FIT),
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
        model_class: str = typer.Option(
            "joints", "--model", help="Model class: joints (the papers', default), extras "
            "gravity, compensator, lost-motion, links combined with '+', or auto (chosen "
            "by BIC and held-out prediction; candidates side by side in results.json).",
            rich_help_panel=_FIT),
        force: bool = typer.Option(False, "--force", help="Replace a non-empty output "
                                   "directory: its contents as a whole, nothing of the "
                                   "earlier analysis is kept.", rich_help_panel=PANEL_OUTPUT),
        db: str = typer.Option(None, "--db", help="Fleet ledger to record the analysis in, "
                               "with a history section in the report (default: the "
                               "STIFFNESS_CAMPAIGN_DB environment variable; neither: none).",
                               rich_help_panel=PANEL_OUTPUT),
        robot_id: str = typer.Option(None, "--robot-id", help="The robot's identity in the "
                                     "ledger when the run names no serial.",
                                     rich_help_panel=PANEL_OUTPUT),
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
        import numpy as np

        from campaign.jobs.analyze import AnalyzeOptions, run
        from campaign.jobs.analyze_noise import NoiseOverrides

        noise = NoiseOverrides.typed(
            translation_sigma_um=_alias(translation_sigma_um, old_translation,
                                        "--translation-sigma-um"),
            rotation_sigma_urad=_alias(rotation_sigma_urad, old_rotation,
                                       "--rotation-sigma-urad"),
            force_sigma_N=force_sigma_n, moment_sigma_Nm=moment_sigma_nm,
            joint_sigma_urad=joint_sigma_urad, force_pct=force_pct, moment_pct=moment_pct)
        poses = [[] if not text.strip() else np.radians(numbers_option(text, f"--pose #{i}"))
                 .tolist() for i, text in enumerate(pose, start=1)]
        options = AnalyzeOptions.with_noise(
            noise, run_dir=run_dir, measurements=measurements, robot=robot, tip=tip, out=out,
            method=method, joints=joints, robust=robust, covariance=covariance,
            poses_rad=poses, wrench_N_Nm=numbers_option(wrench, "--wrench"), trials=trials,
            report=report,
            tool_xyz_mm=numbers_option(tool_xyz_mm, "--tool-xyz-mm"),
            tool_rpy_deg=numbers_option(tool_rpy_deg, "--tool-rpy-deg"),
            accept_misfit=accept_misfit, force=force, ledger=db, robot_id=robot_id,
            model=model_class)
        # with --json, stdout carries the JSON document only
        console = Console(stderr=as_json)
        done = run(options, stage=stage, on_assumptions=lambda a: _print_assumptions(console, a),
                   warn=lambda line: echo(line, err=True))
        result = done.identification
        if as_json:
            for w in result.warnings[done.early_warnings:]:  # on the terminal, beside the JSON
                echo(f"warning: {w}", err=True)  # (the run's were printed on reading)
            print_json(done.to_json())
            return
        _print(console, result, done.files, printed=done.early_warnings, tables=done.tables,
               ledger=done.ledger)
