"""A robot file and a protocol written by the tests (not a shipped model)."""

from __future__ import annotations

import textwrap
from pathlib import Path

ROBOT = """
name = "test arm 6R"
convention = "modified_dh"
length_unit = "m"
angle_unit = "deg"
stiffness_unit = "N m/rad"

[sources]
geometry = "made up by the test"
limits = "made up by the test"
stiffness = "made up by the test"

{joints}
"""

#: (alpha deg, d m, r m, lower deg, upper deg, stiffness N m/rad)
JOINTS = [
    (0, 0.0, 0.55, -170, 170, 6.0e5),
    (90, 0.25, 0.0, -150, 10, 3.0e5),
    (0, 0.90, 0.0, -120, 150, 4.0e5),
    (-90, 0.05, 0.95, -300, 300, 8.0e4),
    (90, 0.0, 0.0, -120, 120, 6.0e4),
    (-90, 0.0, 0.12, -300, 300, 5.0e4),
]

PROTOCOL = """
[campaign]
name = "test arm"
robot = "arm.toml"
tests = 6
repeats = 2

[tool]
xyz_mm = [0, 0, 150]

[instruments.robot]
driver = "manual"
address = "manual://"

[instruments.force_torque]
driver = "ati-netft"
address = "udp://192.168.1.1:49152"
noise = {{ force_N = {force_N}, torque_N_m = {torque_N_m}{pct} }}

[instruments.pose]
driver = "emscon"
address = "socket://192.168.1.10:700"
noise = {{ translation_um = 25, rotation_urad = 30 }}

[instruments.load]
driver = "manual-load"
address = "manual://"

[loads]
selection = "per-pose"

[[load_cases]]
name = "up"
method = "cable-pulley"
force_N = [0, 800, 800]
moment_N_m = [80, 80, 0]

[[load_cases]]
name = "side"
method = "cable-pulley"
force_N = [800, 0, 800]
moment_N_m = [80, -80, 0]

[[load_cases]]
name = "down"
method = "cable-pulley"
force_N = [0, 800, -800]
moment_N_m = [0, 80, 80]

[sampling]
fixed_deg = {{ q1 = 0 }}
ranges_deg = {{ q4 = [-90, 90], q5 = [30, 100], q6 = [-90, 90] }}

[[zones]]
name = "near"
ranges_deg = {{ q2 = [-120, -60], q3 = [20, 80] }}

[[zones]]
name = "far"
ranges_deg = {{ q2 = [-80, -30], q3 = [-40, 20] }}

[thresholds]
min_inv_kappa_F = 0.15
max_v_p = 0.05
max_v_r_deg = 0.1

[safety]
joint_margin_deg = 2
max_force_N = 2000
max_moment_N_m = 300
"""


def write_robot(directory: Path) -> Path:
    """Write ``arm.toml`` in ``directory``; returns its path."""
    rows = []
    for alpha, d, r, lo, hi, k in JOINTS:
        rows.append(f"[[joints]]\nalpha = {alpha}\nd = {d}\nr = {r}\nlower = {lo}\n"
                    f"upper = {hi}\nstiffness = {k}\n")
    path = directory / "arm.toml"
    path.write_text(ROBOT.format(joints="\n".join(rows)))
    return path


def write_protocol(directory: Path, force_N=0.5, torque_N_m=0.05, force_pct=None) -> Path:
    """Write the robot file and ``protocol.toml`` in ``directory``; returns the protocol path."""
    write_robot(directory)
    pct = "" if force_pct is None else f", force_pct = {force_pct}, torque_pct = {force_pct}"
    path = directory / "protocol.toml"
    path.write_text(textwrap.dedent(PROTOCOL.format(force_N=force_N, torque_N_m=torque_N_m,
                                                    pct=pct)))
    return path
