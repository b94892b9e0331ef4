"""``campaign compensate``: deflection along a path under the process load, and the corrected path.

``campaign compensate --robot MODEL --path PATH.csv --out DIR`` writes
``DIR/compensated.csv`` (input columns, predicted deflection of P with 95 %
bounds, compensated joints ``q1_cmd_deg..q6_cmd_deg``, residual),
``DIR/deflection.png``, ``DIR/summary.json`` and a robot program (``--program``;
by default KRL ``comp_path.src/.dat`` for KUKA models, URScript ``comp_path.script``
for UR, RAPID ``comp_path.mod`` for ABB, TP ``COMP_PATH.LS`` for FANUC models).
``--verify-fake --protocol P`` replays both paths on the simulated lab. Formats: ``docs/use.md``.
"""

from __future__ import annotations

from pathlib import Path

import typer

from campaign.cli.terminal import PROGRAM_CHOICES, PROGRAM_METAVAR, Program, WrenchFrame, echo
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP


def _verify_text(stats: dict, readings: int, echo) -> None:
    """The replay on the simulated lab: model vs true stiffness, measured errors."""
    ident = stats["model_vs_true_stiffness_relative"]
    echo("verification on the simulated lab (world driven directly, settled statics; "
         f"{readings} probe reading(s) per point):")
    echo("  model k / true k - 1: " + ", ".join(f"k{j + 1} {100 * v:+.2f} %"
                                                for j, v in enumerate(ident)))
    for name in ("before", "after"):
        s = stats[name]
        echo(f"  measured error {name:6s}: RMS {1e3 * s['rms_m']:.4f} mm (max "
             f"{1e3 * s['max_m']:.4f}), RMS {1e3 * s['rms_rad']:.4f} mrad (max "
             f"{1e3 * s['max_rad']:.4f})")
    echo(f"  after / before (RMS translation): {100 * stats['ratio_rms_translation']:.1f} %")


def register(app: typer.Typer) -> None:
    @app.command("compensate")
    def compensate_cmd(
        robot: str = typer.Option(..., help="Robot: model.toml from campaign analyze, a "
                                  "built-in name, a robot file or a URDF."),
        path: Path = typer.Option(..., help="CSV: q1_deg .. q6_deg per point, optional "
                                  "fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm."),
        out: Path = typer.Option(..., help="Output directory."),
        tip: str = typer.Option(None, help="Tool frame of a URDF."),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP),
        controller: bool = typer.Option(False, "--controller-angles", help="The path's "
                                        "joints are teach-pendant angles (output too)."),
        wrench: str = typer.Option(None, help="Constant wrench fx,fy,fz (N), mx,my,mz (N m) "
                                   "at P when the path has no wrench columns."),
        wrench_frame: WrenchFrame = typer.Option(
            "base", help="Frame of the wrench components: base, or tool (e.g. a spindle "
            "dynamometer's frame)."),
        joint_stiffness: str = typer.Option(None, help="k1,...,k6 (N m/rad) instead of the "
                                            "model's (no uncertainty then)."),
        min_inv_kappa: float = typer.Option(0.02, help="Refuse points where 1/kappa_F of "
                                            "the normalized Jacobian is below this."),
        verify_fake: bool = typer.Option(False, "--verify-fake", help="Replay the original "
                                         "and compensated paths on the simulated lab."),
        protocol: Path = typer.Option(None, help="Protocol whose [fake_lab] is simulated "
                                      "(with --verify-fake)."),
        readings: int = typer.Option(1, help="Probe readings averaged per point "
                                     "(--verify-fake)."),
        program: Program = typer.Option(
            "auto", metavar=PROGRAM_METAVAR, help="Robot program of the compensated path, "
            "one of: " + PROGRAM_CHOICES + "."),
        force: bool = typer.Option(False, "--force", help="Write into a non-empty --out "
                                   "(its files are replaced)."),
    ) -> None:
        """Predict the deflection of P along a path and compute the compensated joints."""
        from campaign.jobs.compensate import CompensateOptions, run
        from campaign.options import numbers_option

        result = run(CompensateOptions(
            robot=robot, path=path, out=out, tip=tip,
            tool_xyz_mm=numbers_option(tool_xyz_mm, "--tool-xyz-mm"),
            tool_rpy_deg=numbers_option(tool_rpy_deg, "--tool-rpy-deg"),
            controller_angles=controller, wrench_N_Nm=numbers_option(wrench, "--wrench"),
            wrench_frame=wrench_frame,
            joint_stiffness_Nm_per_rad=numbers_option(joint_stiffness, "--joint-stiffness"),
            min_inv_kappa=min_inv_kappa, verify_fake=verify_fake, protocol=protocol,
            readings=readings, program=program, force=force))
        summ = result.summary
        for a in summ["assumptions"]:
            echo(f"assumption: {a}")
        t, rr = summ["translation_m"], summ["rotation_rad"]
        bound = ("" if not result.uncertainty else
                 f" (95 % upper bound max {1e3 * t['before_upper95_max']:.4f} mm)")
        echo(f"{summ['points']} points; deflection before: max {1e3 * t['before']['max']:.4f} "
             f"mm, RMS {1e3 * t['before']['rms']:.4f} mm{bound}; rotation max "
             f"{1e3 * rr['before']['max']:.4f} mrad")
        # the residuals are Newton's round-off (refused above 1 um / 1 urad): 3 decimals
        after = ("" if not result.uncertainty else f"; 95 % upper bound from the stiffness "
                 f"uncertainty {1e3 * t['after_upper95_max']:.4f} mm")
        echo(f"after compensation (model): max residual {1e6 * summ['max_residual_m']:.3f} um, "
             f"{1e6 * summ['max_residual_rad']:.3f} urad{after}")
        echo(f"worst point: line {summ['worst_point']['line']} "
             f"({1e3 * summ['worst_point']['deflection_m']:.4f} mm)")
        if "verify_fake" in summ:
            _verify_text(summ["verify_fake"], readings, echo)
        for f in result.files:
            echo(f"wrote {f}")
