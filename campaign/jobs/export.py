"""The ``export`` job: the robot (identified or nominal) as a simulator description, MuJoCo's
MJCF, URDF (springs in Gazebo's extension) or SDFormat 1.9, with the joint stiffness as
joint springs (formats and what each loses: docs/use.md)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from campaign.jobs.choices import SimFormat
from campaign.jobs.option_checks import floats, robot_and_tool

#: file suffixes each format is written under; a suffix of another format is refused
SUFFIXES = {SimFormat.mjcf: (".xml", ".mjcf"), SimFormat.urdf: (".urdf",),
            SimFormat.sdf: (".sdf",)}


@dataclass(frozen=True)
class ExportOptions:
    """robot: a model.toml from campaign analyze, a built-in name, a robot file or a URDF;
    format: the description to write; out: the file; tip: tool frame of a URDF;
    tool_xyz_mm / tool_rpy_deg: P in the flange frame (mm, deg; None: the model's);
    joint_stiffness_Nm_per_rad: springs instead of the model's stiffness;
    no_springs: the kinematic chain alone (no springs); force: replace an existing out."""

    robot: str
    format: SimFormat
    out: Path
    tip: str | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    joint_stiffness_Nm_per_rad: Sequence[float] | None = None
    no_springs: bool = False
    force: bool = False


@dataclass
class ExportResult:
    """file: what was written; stiffness_Nm_per_rad: the springs (None: none written) and
    stiffness_source; report_id: of the analysis the model.toml comes from (None: not an
    identified model, or no results.json beside it); left_out: what the file does not carry;
    notes: what it holds that is not the robot model's (placeholder inertials), K_C."""

    file: Path
    format: str
    robot: str
    source: str
    tool: dict
    stiffness_Nm_per_rad: list | None
    stiffness_source: str
    report_id: str | None
    placeholder_inertials: bool
    left_out: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        """The document ``campaign export --json`` prints (SI units)."""
        return {**self.__dict__, "file": str(self.file)}


def _stiffness(robot, o: ExportOptions) -> tuple[np.ndarray | None, str]:
    """The springs (N m/rad) and where they come from; refused when there are none to write
    and ``--no-springs`` was not given."""
    if o.no_springs and o.joint_stiffness_Nm_per_rad is not None:
        raise InputError("--no-springs and --joint-stiffness contradict each other: give one",
                         where="--no-springs")
    if o.no_springs:
        return None, "none (--no-springs): the kinematic chain alone"
    if o.joint_stiffness_Nm_per_rad is not None:
        k = floats(o.joint_stiffness_Nm_per_rad, "--joint-stiffness", robot.n)
        if np.any(k <= 0):
            raise InputError("joint stiffness values must be positive (N m/rad)",
                             where="--joint-stiffness")
        return k, "--joint-stiffness"
    if robot.nominal_stiffness is None:
        raise InputError(f"{robot.name} has no joint stiffness (none in its robot file, not an "
                         "identified model.toml): give --joint-stiffness k1,...,k6 (N m/rad), "
                         "or --no-springs to export the kinematic chain alone",
                         where="--robot")
    if robot.identification is not None:
        return robot.nominal_stiffness, "identified (model.toml of campaign analyze)"
    return robot.nominal_stiffness, "nominal (the robot file's)"


def _report_id(robot) -> str | None:
    """report_id of the results.json beside an identified model file that names it as its
    ``model_file`` (campaign analyze writes both into one directory), else None."""
    if robot.identification is None or not robot.source_file:
        return None
    results = Path(robot.source_file).parent / "results.json"
    try:
        doc = json.loads(results.read_text())
    except (OSError, ValueError):
        return None
    rid = doc.get("report_id") if isinstance(doc, dict) else None
    # results.json names the model file it wrote beside itself: another file there is not it
    named = doc.get("model_file") == Path(robot.source_file).name
    return str(rid) if rid and named else None


def _out_path(o: ExportOptions) -> Path:
    out = Path(o.out)
    fmt = SimFormat(o.format)
    suffix = out.suffix.lower()
    others = {s for f, ss in SUFFIXES.items() if f != fmt for s in ss}
    if suffix in others:
        raise InputError(f"a {suffix} name for a {fmt} file: name it "
                         f"{' or '.join(SUFFIXES[fmt])}, or choose --format to match",
                         where="--out")
    if (out.exists() or out.is_symlink()) and not o.force:
        raise InputError("exists; choose another name or add --force to replace it",
                         where=f"--out {out}")
    return out


def _header(robot, o: ExportOptions, source: str, stiffness_source: str, report_id,
            tool_text: str) -> list[str]:
    lines = [f"{robot.name}: written by campaign export (robot-stiffness-campaign) from "
             f"{source}", f"report_id: {report_id or 'none'}", f"tool point: {tool_text}",
             f"joint stiffness: {stiffness_source}"]
    ident = robot.identification
    if ident is not None:
        lines.append(f"identified by campaign analyze ({ident['method']}, {ident['n_tests']} "
                     f"tests) from {ident['source_run']}, {ident['date']}; joints identified "
                     f"{ident['joints_identified']}, nominal {ident['joints_nominal']}")
    return lines


def run(o: ExportOptions) -> ExportResult:
    """Load the robot, choose its springs and write the description to ``o.out``."""
    from analysis.export.mjcf import mjcf_text
    from analysis.export.sdf import sdf_text
    from analysis.export.sim_model import sim_model
    from analysis.export.urdf import urdf_text
    from analysis.model.robot_spec import is_robot_file
    from analysis.output_files import write_text

    fmt = SimFormat(o.format)
    out = _out_path(o)
    robot, tool = robot_and_tool(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    k, k_source = _stiffness(robot, o)
    source = (str(robot.source_file) if is_robot_file(o.robot) else
              f"built-in robot {robot.key} ({Path(str(robot.source_file)).name})")
    rid = _report_id(robot)
    model = sim_model(robot, k, _header(robot, o, source, k_source, rid, tool.text()))
    writer = {SimFormat.mjcf: mjcf_text, SimFormat.urdf: urdf_text, SimFormat.sdf: sdf_text}
    write_text(out, writer[fmt](model))
    return ExportResult(
        file=out, format=str(fmt), robot=robot.name, source=source, tool=tool.describe(),
        stiffness_Nm_per_rad=None if k is None else np.asarray(k, float).tolist(),
        stiffness_source=k_source, report_id=rid,
        placeholder_inertials=model.placeholder_inertials, left_out=list(model.left_out),
        notes=list(model.notes))
