"""The ``compensate`` job: the deflection of P along a path under the process load, the
compensated joints and a robot program; optionally a replay on the simulated lab.

Writes OUT/compensated.csv, OUT/deflection.png, OUT/summary.json and the program
(see ``campaign compensate --help`` and docs/use.md for the formats).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from campaign.jobs.choices import Program
from campaign.jobs.path_deflection import PathDeflectionOptions, load_path


@dataclass(frozen=True, kw_only=True)
class CompensateOptions(PathDeflectionOptions):
    """The path and its load as the path_deflection job's options (robot, path, tip,
    tool_xyz_mm, tool_rpy_deg, controller_angles, wrench_N_Nm, wrench_frame,
    joint_stiffness_Nm_per_rad, min_inv_kappa; those two positional), and given by name:
    out: the output directory; verify_fake + protocol: replay both paths on that
    protocol's simulated lab with ``readings`` probe readings; program: the robot
    program's language; force: replace the files of a non-empty out."""

    out: Path
    verify_fake: bool = False
    protocol: Path | None = None
    readings: int = 1
    program: Program = Program.auto
    force: bool = False


@dataclass
class CompensateResult:
    """summary: OUT/summary.json (SI units; assumptions, and ``verify_fake`` statistics when
    replayed); files: the files written, in the order the command lists them."""

    summary: dict
    files: list[Path] = field(default_factory=list)
    #: the stiffness has a covariance (identified model, no --joint-stiffness): 95 % bounds
    uncertainty: bool = False

    def to_json(self) -> dict:
        return {**self.summary, "files": [str(f) for f in self.files]}


def _verify(protocol: Path, robot, pin, pc, readings: int) -> tuple:
    from campaign.use.verify_fake import run_on_fake_lab

    check = run_on_fake_lab(protocol, robot, pin.q, pc.comp.q_cmd, pin.w, readings)
    stats = check.stats()
    ident = np.asarray(robot.nominal_stiffness, float) / check.true_k - 1.0
    stats["model_vs_true_stiffness_relative"] = ident.tolist()
    return stats, check


def run(o: CompensateOptions) -> CompensateResult:
    """Read the path, compensate it and write the output directory."""
    from analysis.kinetostatics.path_compensation import compensate_path
    from analysis.output_files import check_output_dir, make_dir, replacing, write_text
    from campaign.use import compensate_output as co

    if o.verify_fake and o.protocol is None:
        raise InputError("--verify-fake needs --protocol P (the lab to simulate)",
                         where="--protocol")
    if o.readings < 1:
        raise InputError("expected at least 1 reading", where="--readings")
    loaded = load_path(o)
    r, cov, pin = loaded.robot, loaded.cov, loaded.path
    path, out = Path(o.path), Path(o.out)
    pc = compensate_path(r, pin.q, loaded.k, pin.w, cov, pin.line, str(path), o.min_inv_kappa)
    check_output_dir(out, o.force)
    table = co.output_table(pin.frame, pc, r, o.controller_angles)
    make_dir(out)
    with replacing(out / "compensated.csv") as tmp:
        table.to_csv(tmp, index=False)
    convention = "pendant" if o.controller_angles else "model"
    assumptions = [
        f"robot {r.name} from {r.source_file or o.robot}",
        f"joint stiffness: {loaded.stiffness_source}",
        "uncertainty: " + ("covariance of the identified compliances, delta method"
                           if cov is not None else "none (no covariance in the model)"),
        f"wrench: {pin.wrench_source}",
        "deflection: nonlinear equilibrium K dq = J(q + dq)^T w, base frame at P",
        f"joints: {convention} convention in and out; programs in the pendant convention",
    ]
    if pc.flanks is not None and (np.any(pc.flanks.offset) or np.any(pc.flanks.unknown)):
        assumptions.append(co.lost_motion_text(pc.flanks, pin.line))
    summ = co.summary(pc, pin.line)
    summ["assumptions"] = assumptions
    files = [out / "compensated.csv"]
    files += co.robot_program(r, pc.comp.q_cmd, out, [
        f"Compensated path from {path.name} ({len(pin.q)} points), campaign compensate",
        f"Robot model: {r.name}", f"Wrench: {pin.wrench_source}"], str(o.program))
    check = None
    if o.verify_fake:
        summ["verify_fake"], check = _verify(Path(o.protocol), r, pin, pc, o.readings)
    # drawn after the verification: the measured errors go on the same plot
    files.insert(1, co.plot(pc, out / "deflection.png", f"{r.name}: deflection of P "
                            f"along {path.name}", check))
    write_text(out / "summary.json", json.dumps(summ, indent=2) + "\n")
    files.append(out / "summary.json")
    return CompensateResult(summ, files, cov is not None)
