"""What an analysis rests on, read from a run directory (``docs/run_format.md``) or a tests
CSV file and its sidecar: the tests as arrays, the robot model, the noise model of one test
row, the campaign's facts and the protocol, in one frozen :class:`AnalysisInput`."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from analysis.errors import InputError
from analysis.identification.noise import NoiseModel
from campaign.jobs.option_checks import six_joints
from campaign.options import ToolPoint, file_tool_point, robot_and_tool, tool_option
from campaign.run_noise import noise_from_protocol, protocol_noise_source

if TYPE_CHECKING:  # pandas and the report's records: not at start-up
    from analysis.identification.io.measurements import TestArrays
    from analysis.model.robot_model import RobotModel
    from analysis.report.summary import CampaignInfo
    from campaign.protocol import Protocol


@dataclass(frozen=True)
class AnalysisInput:
    """The tests to identify from (:class:`TestArrays`, SI), the robot model (with its tool),
    the noise model of one test row and where its figures come from, the campaign's facts
    (:class:`analysis.report.summary.CampaignInfo`), the protocol (None for a CSV file), the
    simulated lab's true joint stiffness (N m/rad; None unless simulated), the tool point,
    where the robot comes from, and whether the tests came from a CSV file."""

    tests: TestArrays
    robot: RobotModel
    noise: NoiseModel
    noise_source: str
    info: CampaignInfo
    protocol: Protocol | None
    true_k: np.ndarray | None
    tool: ToolPoint
    robot_source: str
    imported: bool = False


def output_dir(run_dir: Path | None, measurements: Path | None, robot: str | None,
               out: Path | None, force: bool) -> Path:
    """The analysis's output directory (default RUN_DIR/analysis; a CSV file needs one),
    checked before anything is read: a non-empty one is refused unless ``force``. Refuses
    a run directory and a CSV file together (or neither), and a robot beside a run."""
    from analysis.output_files import check_output_dir

    if (run_dir is None) == (measurements is None):
        raise InputError("give either RUN_DIR or --measurements FILE.csv --robot R",
                         where="campaign analyze")
    if run_dir is not None:
        if robot:
            raise InputError("a run names its robot in its protocol; drop --robot",
                             where="--robot")
        out = out or run_dir / "analysis"
    elif out is None:
        raise InputError("--measurements needs --out DIR", where="--out")
    check_output_dir(out, force, "--out", replaces="replace its contents")
    return out


def read_input(run_dir: Path | None, measurements: Path | None, robot: str | None,
               tip: str | None, tool_xyz: str | None, tool_rpy: str | None,
               warn: Callable[[str], None]) -> AnalysisInput:
    """The :class:`AnalysisInput` of a run directory or else a tests CSV file with
    ``robot`` (built-in name, robot file or URDF; ``tip``: its tool frame); the tool point's
    texts (mm, deg) override the protocol's or sidecar's; ``warn(line)`` gets a damaged
    run's loud warnings as it is read."""
    if run_dir is not None:
        return _from_run(run_dir, tool_xyz, tool_rpy, warn)
    return _from_csv(measurements, robot, tip, tool_xyz, tool_rpy)


def _from_run(run_dir: Path, tool_xyz: str | None, tool_rpy: str | None,
              warn: Callable[[str], None]) -> AnalysisInput:
    """The :class:`AnalysisInput` of a run directory: its good rows as arrays (the
    run's text table is let go when this returns)."""
    from analysis.identification.io.measurements import to_arrays
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
    ok = run.ok
    del run  # the run's whole text table goes before the arrays are made (as before)
    return AnalysisInput(to_arrays(ok), robot, noise, noise_source, info, protocol,
                         None if true_k is None else np.asarray(true_k, float), tool,
                         robot_source)


def _sha256(path: Path) -> str:
    """SHA-256 of a file read in 1 MB chunks (a 1e6-row CSV is ~150 MB)."""
    import hashlib

    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _from_csv(path: Path, robot_spec: str | None, tip: str | None, tool_xyz: str | None,
              tool_rpy: str | None) -> AnalysisInput:
    """The :class:`AnalysisInput` of a tests CSV file and its sidecar, if any; the tests
    read straight into arrays (a 1e6-row file never becomes a table)."""
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
    return AnalysisInput(tests, robot, noise, noise_source, info, None, None, tool,
                         robot_source, imported=True)


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
        operator=operator_text(meta), status=run.status, reason=run.reason,
        protocol_file=str(meta.get("protocol_file") or run.protocol_path or "-"),
        protocol_sha256=run.protocol_sha256 or str(meta.get("protocol_sha256") or "-"),
        software={str(k): str(v) for k, v in (meta.get("software") or {}).items()},
        n_planned=run.n_planned, n_rows=len(run.tests), n_ok=len(run.ok),
        n_failed=run.n_failed, flagged=flagged, flag_counts=run.flag_counts(),
        notes=list(run.notes), **run_trace(run, protocol),
    )


def operator_text(meta: dict) -> str:
    """The operator recorded in metadata.json, saying when it is only the OS login name (a
    run recorded without --operator; older runs do not say where the name came from)."""
    name = str(meta.get("operator") or "-")
    source = meta.get("operator_source")
    if name != "-" and source and source != "--operator":
        return f"{name} ({source})"
    return name
