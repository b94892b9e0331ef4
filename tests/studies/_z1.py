"""A second robot for the coverage study: the Unitree Z1 arm of example-robot-data (URDF).

The project ships no model of it; its URDF comes with the ``example-robot-data`` wheel
(installed with the test extras). Its axes are not those of a DH industrial arm (z, y,
y, y, z, x; the tool frame ``gripperStator`` is both a link and the fixed joint above
it), and it is two orders of magnitude softer and lighter than the KR240-2: joint
stiffness 1.2-14 kN m/rad (made up, of the order of a small harmonic-drive arm), loads of
57 N and 5.7 N m.
"""

from __future__ import annotations

import shutil
import sysconfig
import textwrap
from pathlib import Path

URDF = (Path(sysconfig.get_paths()["purelib"])
        / "cmeel.prefix/share/example-robot-data/robots/z1_description/urdf/z1.urdf")

PROTOCOL = """
[campaign]
name = "Unitree Z1 (example-robot-data URDF)"
robot = "z1.urdf#gripperStator"
tests = 5
repeats = 1
prior_stiffness = [9000, 14000, 7000, 2500, 2000, 1200]

[tool]
xyz_mm = [60, 0, 0]

[instruments.robot]
driver = "manual"
address = "manual://"

[instruments.force_torque]
driver = "ati-netft"
address = "udp://192.168.1.1:49152"
noise = { force_N = 0.5, torque_N_m = 0.05 }

[instruments.pose]
driver = "emscon"
address = "socket://192.168.1.10:700"
noise = { translation_um = 30, rotation_urad = 40 }

[instruments.load]
driver = "manual-load"
address = "manual://"

[loads]
selection = "per-pose"

[[load_cases]]
name = "a"
method = "cable-pulley"
force_N = [0, 40, 40]
moment_N_m = [4, 4, 0]

[[load_cases]]
name = "b"
method = "cable-pulley"
force_N = [40, 0, -40]
moment_N_m = [-4, 0, 4]

[[load_cases]]
name = "c"
method = "cable-pulley"
force_N = [-40, 40, 0]
moment_N_m = [0, -4, 4]

[[zones]]
name = "front"
[zones.ranges_deg]
q1 = [-60, 60]
q2 = [20, 150]
q3 = [-150, -20]
q4 = [-60, 60]
q5 = [-60, 60]
q6 = [-90, 90]

[thresholds]
min_inv_kappa_F = 0.15
max_v_p = 0.05
max_v_r_deg = 0.1
"""


def write_protocol(directory: Path) -> Path:
    """Copy the Z1 URDF into ``directory`` and write ``protocol.toml`` beside it.

    Raises
    ------
    FileNotFoundError
        When example-robot-data is not installed (the message names the package).
    """
    if not URDF.is_file():
        raise FileNotFoundError(f"the Z1 URDF needs the example-robot-data package ({URDF})")
    shutil.copy(URDF, directory / "z1.urdf")
    path = directory / "protocol.toml"
    path.write_text(textwrap.dedent(PROTOCOL))
    return path
