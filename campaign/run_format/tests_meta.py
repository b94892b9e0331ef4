"""The sidecar that makes a tests CSV file self-describing: ``tests.meta.json``.

``campaign acquire`` writes it next to the run's ``tests.csv``; ``campaign
analyze --measurements FILE.csv`` reads ``FILE.meta.json`` when it exists, so
a run's tests re-imported as a CSV file are analysed at the same tool point
with the same noise figures as the run. A sidecar rather than a commented
header keeps the CSV file readable as is by pandas, Excel and the like.

Format (JSON object, version 1)::

    {"format": "stiffness-campaign tests sidecar", "version": 1,
     "csv": "tests.csv",
     "robot": {"name": "...", "key": "ur10e"},            # key: built-in name or file
     "tool": {"xyz_mm": [x, y, z], "rpy_deg": [r, p, y], "mass_kg": m, "frame": "flange"},
     "noise": {"translation_sigma_m": s, "rotation_sigma_rad": s, "force_sigma_N": s,
               "moment_sigma_Nm": s, "encoder_resolution_rad": s,
               "source": "...", "per": "one test row"},
     "conventions": {...}, "protocol_sha256": "..."}

Every field but ``format`` and ``version`` may be absent; absent figures fall
back to the defaults, and the analysis says so.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from analysis.errors import InputError
from analysis.identification.noise import NoiseModel
from campaign.options import ToolPoint

FORMAT = "stiffness-campaign tests sidecar"
VERSION = 1
#: what the columns of a tests CSV file mean (written into every sidecar)
CONVENTIONS = {
    "joint_angles": "q1_deg..q6_deg: robot model convention, deg",
    "wrench": "fx_N..mz_Nm: wrench applied to the end-effector at the tool point P, "
              "base-frame components, N and N m",
    "displacement": "dx_mm..dz_mm: translation of P, base frame, mm; rx_mrad..rz_mrad: small "
                    "rotation vector, base frame, mrad (loaded - unloaded)",
    "tool_point": "P in the flange frame: xyz_mm, then roll-pitch-yaw rpy_deg",
}


def sidecar_path(csv_path: str | Path) -> Path:
    """``tests.csv`` -> ``tests.meta.json`` (same directory)."""
    csv_path = Path(csv_path)
    return csv_path.with_name(csv_path.stem + ".meta.json")


@dataclass(frozen=True)
class TestsMeta:
    """What a sidecar says about its CSV file.

    robot_key, robot_name : the robot (built-in name or file) and its name, or None.
    tool : the tool point P (source names the sidecar), or None when absent.
    noise : the noise model of one test row, or None when absent.
    noise_source : where the sidecar's figures came from.
    path : the sidecar file.
    """

    __test__ = False

    robot_key: str | None
    robot_name: str | None
    tool: ToolPoint | None
    noise: NoiseModel | None
    noise_source: str
    path: Path


def sidecar_record(*, robot_key: str | None, robot_name: str | None, tool_xyz_mm,
                   tool_rpy_deg, tool_mass_kg: float, noise: NoiseModel, noise_source: str,
                   csv_name: str = "tests.csv", protocol_sha256: str | None = None) -> dict:
    """The JSON object of a sidecar (see the module docstring)."""
    return {
        "format": FORMAT, "version": VERSION, "csv": csv_name,
        "robot": {"name": robot_name, "key": robot_key},
        "tool": {"xyz_mm": [float(v) for v in tool_xyz_mm],
                 "rpy_deg": [float(v) for v in tool_rpy_deg],
                 "mass_kg": float(tool_mass_kg), "frame": "flange"},
        "noise": {"translation_sigma_m": noise.translation_sigma,
                  "rotation_sigma_rad": noise.rotation_sigma,
                  "force_sigma_N": noise.force_sigma, "moment_sigma_Nm": noise.moment_sigma,
                  "encoder_resolution_rad": noise.encoder_resolution,
                  "source": noise_source, "per": "one test row"},
        "conventions": CONVENTIONS,
        "protocol_sha256": protocol_sha256,
    }


def write_sidecar(csv_path: str | Path, record: dict) -> Path:
    """Write ``record`` next to ``csv_path`` (atomically: temporary file, then rename)."""
    from analysis.output_files import write_text

    path = sidecar_path(csv_path)
    write_text(path, json.dumps(record, indent=2) + "\n")
    return path


def _numbers(value, n: int, where: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        out = ()
    if len(out) != n or not all(abs(v) < float("inf") for v in out):
        raise InputError(f"expected {n} finite numbers, got {value!r}", where=where)
    return out


def read_sidecar(csv_path: str | Path) -> TestsMeta | None:
    """The sidecar of ``csv_path``, or None when there is none.

    Raises
    ------
    InputError
        The sidecar exists but is not a readable sidecar (the message names the field).
    """
    path = sidecar_path(csv_path)
    if not path.is_file():
        return None
    where = str(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as err:
        raise InputError(f"cannot read the sidecar as JSON: {err}", where=where) from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise InputError(f"not a tests sidecar (expected \"format\": \"{FORMAT}\")", where=where)
    if data.get("version") != VERSION:
        raise InputError(f"sidecar version {data.get('version')!r} is not {VERSION}",
                         where=where)
    robot = data.get("robot") or {}
    tool = None
    if isinstance(data.get("tool"), dict):
        t = data["tool"]
        tool = ToolPoint(_numbers(t.get("xyz_mm", (0, 0, 0)), 3, f"{where}: tool.xyz_mm"),
                         _numbers(t.get("rpy_deg", (0, 0, 0)), 3, f"{where}: tool.rpy_deg"),
                         f"sidecar {path.name}")
    noise, source = None, ""
    if isinstance(data.get("noise"), dict):
        n = data["noise"]
        keys = {"translation_sigma_m": "translation_sigma_override",
                "rotation_sigma_rad": "rotation_sigma_override",
                "force_sigma_N": "force_sigma", "moment_sigma_Nm": "moment_sigma",
                "encoder_resolution_rad": "encoder_resolution"}
        values = {}
        for key, field in keys.items():
            if n.get(key) is not None:
                values[field] = _numbers([n[key]], 1, f"{where}: noise.{key}")[0]
        try:
            noise = NoiseModel().with_overrides(**values)
        except InputError as err:
            raise InputError(str(err), where=f"{where}: noise") from None
        source = f"sidecar {path.name}: {n.get('source') or 'source not recorded'}"
    return TestsMeta(robot_key=robot.get("key"), robot_name=robot.get("name"), tool=tool,
                     noise=noise, noise_source=source, path=path)
