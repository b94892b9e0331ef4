"""The ``compensate`` job: the deflection of P along a path under the process load, the
compensated joints and a robot program; optionally a replay on the simulated lab.

Writes OUT/compensated.csv, OUT/deflection.png, OUT/summary.json and the program
(see ``campaign compensate --help`` and docs/use.md for the formats).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from campaign.jobs.choices import Program, WrenchFrame
from campaign.jobs.common import floats, joint_stiffness, robot_and_tool


@dataclass(frozen=True)
class CompensateOptions:
    """robot: model.toml from analyze, a built-in name, robot file or URDF; path: the path CSV
    (q1_deg..q6_deg per point as the file format says, optional wrench columns);
    out: the output directory; tip, tool_xyz_mm, tool_rpy_deg: as the stiffness job's;
    controller_angles: the path's joints are pendant angles (the output too);
    wrench_N_Nm: constant wrench at P when the path has none; wrench_frame: base or tool;
    joint_stiffness_Nm_per_rad: instead of the model's (no uncertainty then);
    min_inv_kappa: refuse points where 1/kappa_F is below it; verify_fake + protocol:
    replay both paths on that protocol's simulated lab with ``readings`` probe readings;
    program: the robot program's language; force: replace the files of a non-empty out."""

    robot: str
    path: Path
    out: Path
    tip: str | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    controller_angles: bool = False
    wrench_N_Nm: Sequence[float] | None = None
    wrench_frame: WrenchFrame = WrenchFrame.base
    joint_stiffness_Nm_per_rad: Sequence[float] | None = None
    min_inv_kappa: float = 0.02
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
    from campaign.use.path_file import read_path

    if o.verify_fake and o.protocol is None:
        raise InputError("--verify-fake needs --protocol P (the lab to simulate)",
                         where="--protocol")
    if o.readings < 1:
        raise InputError("expected at least 1 reading", where="--readings")
    if not o.min_inv_kappa > 0:
        raise InputError("expected a positive number", where="--min-inv-kappa")
    r, _ = robot_and_tool(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    if r.n != 6:
        raise InputError(f"{r.name} has {r.n} joints; paths have 6", where="--robot")
    k = joint_stiffness(r, o.joint_stiffness_Nm_per_rad)
    given_k = o.joint_stiffness_Nm_per_rad is not None
    cov = None if given_k else r.compliance_covariance
    w_const = None if o.wrench_N_Nm is None else floats(o.wrench_N_Nm, "--wrench", 6)
    path, out = Path(o.path), Path(o.out)
    pin = read_path(path, r, o.controller_angles, w_const, str(o.wrench_frame))
    pc = compensate_path(r, pin.q, k, pin.w, cov, pin.line, str(path), o.min_inv_kappa)
    check_output_dir(out, o.force)
    table = co.output_table(pin.frame, pc, r, o.controller_angles)
    make_dir(out)
    with replacing(out / "compensated.csv") as tmp:
        table.to_csv(tmp, index=False)
    convention = "pendant" if o.controller_angles else "model"
    assumptions = [
        f"robot {r.name} from {r.source_file or o.robot}",
        "joint stiffness: " + ("--joint-stiffness" if given_k else
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
