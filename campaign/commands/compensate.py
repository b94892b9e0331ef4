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

import json
from pathlib import Path

import numpy as np
import typer

from analysis.errors import InputError
from campaign.cli_common import (
    PROGRAM_CHOICES,
    PROGRAM_METAVAR,
    Program,
    WrenchFrame,
    output_dir,
)
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP


def _verify(protocol: Path, robot, pin, pc, readings: int, echo) -> tuple:
    from campaign.verify_fake import run_on_fake_lab

    check = run_on_fake_lab(protocol, robot, pin.q, pc.comp.q_cmd, pin.w, readings)
    stats = check.stats()
    ident = np.asarray(robot.nominal_stiffness, float) / check.true_k - 1.0
    stats["model_vs_true_stiffness_relative"] = ident.tolist()
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
    return stats, check


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
        from analysis.kinetostatics.path_compensation import compensate_path
        from campaign import compensate_output as co
        from campaign.options import parse_floats, robot_option, stiffness_option
        from campaign.path_file import read_path

        if verify_fake and protocol is None:
            raise InputError("--verify-fake needs --protocol P (the lab to simulate)",
                             where="--protocol")
        if readings < 1:
            raise InputError("expected at least 1 reading", where="--readings")
        if not min_inv_kappa > 0:
            raise InputError("expected a positive number", where="--min-inv-kappa")
        r = robot_option(robot, tip, tool_xyz_mm, tool_rpy_deg)
        if r.n != 6:
            raise InputError(f"{r.name} has {r.n} joints; paths have 6", where="--robot")
        k = stiffness_option(r, joint_stiffness)
        cov = None if joint_stiffness is not None else r.compliance_covariance
        w_const = None if wrench is None else parse_floats(wrench, "--wrench", 6)
        pin = read_path(path, r, controller, w_const, str(wrench_frame))
        pc = compensate_path(r, pin.q, k, pin.w, cov, pin.line, str(path), min_inv_kappa)
        output_dir(out, force)
        table = co.output_table(pin.frame, pc, r, controller)
        from analysis.output_files import make_dir, replacing, write_text

        make_dir(out)
        with replacing(out / "compensated.csv") as tmp:
            table.to_csv(tmp, index=False)
        convention = "pendant" if controller else "model"
        assumptions = [
            f"robot {r.name} from {r.source_file or robot}",
            "joint stiffness: " + ("--joint-stiffness" if joint_stiffness else
                                   "identified (model.toml)" if r.identification else
                                   "nominal (robot file)"),
            "uncertainty: " + ("covariance of the identified compliances, delta method"
                               if cov is not None else "none (no covariance in the model)"),
            f"wrench: {pin.wrench_source}",
            "deflection: nonlinear equilibrium K dq = J(q + dq)^T w, base frame at P",
            f"joints: {convention} convention in and out; programs in the pendant convention",
        ]
        summ = co.summary(pc, pin.line)
        summ["assumptions"] = assumptions
        files = [out / "compensated.csv"]
        files += co.robot_program(r, pc.comp.q_cmd, out, [
            f"Compensated path from {path.name} ({len(pin.q)} points), campaign compensate",
            f"Robot model: {r.name}", f"Wrench: {pin.wrench_source}"], str(program))
        from campaign.cli_common import echo
        for a in assumptions:
            echo(f"assumption: {a}")
        t, rr = summ["translation_m"], summ["rotation_rad"]
        bound = ("" if cov is None else
                 f" (95 % upper bound max {1e3 * t['before_upper95_max']:.4f} mm)")
        echo(f"{summ['points']} points; deflection before: max {1e3 * t['before']['max']:.4f} "
             f"mm, RMS {1e3 * t['before']['rms']:.4f} mm{bound}; rotation max "
             f"{1e3 * rr['before']['max']:.4f} mrad")
        # the residuals are Newton's round-off (refused above 1 um / 1 urad): 3 decimals
        after = ("" if cov is None else f"; 95 % upper bound from the stiffness uncertainty "
                 f"{1e3 * t['after_upper95_max']:.4f} mm")
        echo(f"after compensation (model): max residual {1e6 * summ['max_residual_m']:.3f} um, "
             f"{1e6 * summ['max_residual_rad']:.3f} urad{after}")
        echo(f"worst point: line {summ['worst_point']['line']} "
             f"({1e3 * summ['worst_point']['deflection_m']:.4f} mm)")
        check = None
        if verify_fake:
            summ["verify_fake"], check = _verify(protocol, r, pin, pc, readings, echo)
        # drawn after the verification: the measured errors go on the same plot
        files.insert(1, co.plot(pc, out / "deflection.png", f"{r.name}: deflection of P "
                                f"along {path.name}", check))
        write_text(out / "summary.json", json.dumps(summ, indent=2) + "\n")
        files.append(out / "summary.json")
        for f in files:
            echo(f"wrote {f}")
