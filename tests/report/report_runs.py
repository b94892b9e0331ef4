"""Run directories for the report tests, in the layout of ``docs/run_format.md``.

The displacements are simulated with the nonlinear equilibrium
(:func:`analysis.kinetostatics.equilibrium.displacement_screw`) of the KR240-2 at the
paper's Table 2 stiffness, plus normal noise of the protocol's instrument
sigmas (30 um, 20 urad per reading) as ``campaign acquire`` produces it
(displacement = loaded - mean of the two unloaded readings: sqrt(1.5) times
the reading sigma), seeded.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.robots import load_robot

ROOT = Path(__file__).resolve().parents[2]
PROTOCOL = ROOT / "protocols" / "kr240-2.toml"
TRUE_K = np.array([1409800.0, 400760.0, 935280.0, 360000.0, 370000.0, 380000.0])
SIGMA = np.array([30e-6] * 3 + [20e-6] * 3) * np.sqrt(1.5)
#: Five poses in the paper's zones (model convention, deg) and the load case of each.
POSES_DEG = np.array([
    [0, 40, -200, 45, 45, 45],
    [20, 80, -220, 30, 60, -30],
    [0, 10, 15, 45, 45, 45],
    [-20, 120, 15, 60, 30, 10],
    [10, 60, -180, -40, 50, 80],
], dtype=float)
LOADS = ["eq22", "eq22-mirror-y", "eq22-x", "eq22-down", "eq22"]
WRENCH = {
    "eq22": [0, 2200, 2200, 200, 200, 0],
    "eq22-mirror-y": [0, -2200, 2200, -200, 200, 0],
    "eq22-x": [2200, 0, 2200, 200, -200, 0],
    "eq22-down": [0, 2200, -2200, 200, 200, 0],
}
REPEATS = 3
HEADER = (
    ["pose"] + [f"q{i}_deg" for i in range(1, 7)]
    + ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]
    + ["dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"]
    + ["test_id", "repeat", "status", "flags", "repeatability_mm", "drift_mm",
       "wrench_error_N", "tracker_sigma_mm", "t_utc"]
)


def simulated_rows(seed: int = 1) -> list[dict]:
    """One dict per (test, repeat) with the columns of ``tests.csv`` (CSV units)."""
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(seed)
    q = np.radians(np.repeat(POSES_DEG, REPEATS, axis=0))
    w = np.array([WRENCH[LOADS[i // REPEATS]] for i in range(len(q))], dtype=float)
    d = displacement_screw(robot, q, TRUE_K, w) + rng.normal(size=(len(q), 6)) * SIGMA
    rows = []
    for i in range(len(q)):
        t = i // REPEATS
        rows.append({
            "pose": f"P{t + 1}", **{f"q{j + 1}_deg": POSES_DEG[t, j] for j in range(6)},
            **dict(zip(HEADER[7:13], w[i], strict=True)),
            **dict(zip(HEADER[13:16], 1e3 * d[i, :3], strict=True)),
            **dict(zip(HEADER[16:19], 1e3 * d[i, 3:], strict=True)),
            "test_id": t + 1, "repeat": i % REPEATS + 1, "status": "ok", "flags": "",
            "repeatability_mm": 0.012, "drift_mm": 0.004, "wrench_error_N": 0.6,
            "tracker_sigma_mm": 0.03, "t_utc": f"2026-11-20T10:{i:02d}:00Z",
        })
    return rows


def write_csv(path: Path, rows: list[dict]) -> Path:
    """The rows in the public CSV import format (the first 19 columns)."""
    lines = [",".join(HEADER[:19])] + [",".join(_cell(r[c]) for c in HEADER[:19]) for r in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def _cell(v) -> str:
    if isinstance(v, float):
        return repr(float(v))
    return str(v)


def write_run(path: Path, rows: list[dict], status: str = "complete", reason: str = "",
              truncate_last: bool = False, protocol_extra: str = "", fake: bool = True,
              pose_keys: str = "") -> Path:
    """Write a run directory with ``rows`` as ``tests.csv``; returns ``path``.

    ``protocol_extra`` is appended to the protocol copy (e.g. a ``[report]`` table),
    ``pose_keys`` (TOML lines) added to its ``[instruments.pose]`` table. ``fake``: the
    run came from the simulated lab (metadata ``fake`` and ``fake_lab``); False: neither.
    """
    path.mkdir(parents=True, exist_ok=True)
    text = PROTOCOL.read_text() + protocol_extra
    if pose_keys:
        text = text.replace("[instruments.pose]\n", f"[instruments.pose]\n{pose_keys}\n", 1)
    (path / "protocol.toml").write_text(text)
    meta = {
        "format_version": 1, "status": status, "reason": reason,
        "started_utc": "2026-11-20T09:58:00Z",
        "ended_utc": None if status == "running" else "2026-11-20T10:30:00Z",
        "operator": "test bench", "protocol_file": "protocols/kr240-2.toml",
        "protocol_sha256": hashlib.sha256(text.encode()).hexdigest(),
        "robot": {"name": "KUKA KR240-2", "key": "kr240-2"},
        "tool": {"xyz_mm": [0, 0, 0], "rpy_deg": [0, 0, 0], "mass_kg": 0},
        "instruments": {
            "pose": {"driver": "emscon", "address": "socket://192.168.1.10:700",
                     "serial": "LT-123", "units": "mm"},
            "force_torque": {"driver": "ati-netft", "address": "udp://192.168.1.1:49152",
                             "units": "N, N m"},
        },
        "software": {"stiffness-campaign": "0.1.0", "numpy": np.__version__},
        "plan_file": "plan.csv", "n_planned_tests": 5, "repeats": REPEATS,
        "fake": fake,
        "fake_lab": {"true_joint_stiffness": TRUE_K.tolist()} if fake else None,
    }
    (path / "metadata.json").write_text(json.dumps(meta, indent=2))
    lines = [",".join(HEADER)] + [",".join(_cell(r[c]) for c in HEADER) for r in rows]
    body = "\n".join(lines) + "\n"
    if truncate_last:
        body = body[: body.rstrip("\n").rfind(",") ]
    (path / "tests.csv").write_text(body)
    (path / "events.jsonl").write_text(
        json.dumps({"t_utc": "2026-11-20T09:58:00Z", "event": "start"}) + "\n")
    return path
