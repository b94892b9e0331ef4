"""Parsing of command-line values: lists of numbers with units, robot selection.

Every command that takes ``--robot`` declares the same four options,
``--robot``, ``--tip``, ``--tool-xyz-mm`` and ``--tool-rpy-deg`` (use
:data:`TOOL_XYZ_HELP` / :data:`TOOL_RPY_HELP`), and resolves them with one
call to :func:`robot_option`, so the tool point P means the same everywhere:
the protocol's ``[tool]`` (xyz in mm and roll-pitch-yaw in deg of P in the
flange frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from analysis.errors import InputError

if TYPE_CHECKING:
    import numpy as np

    from analysis.model.robot_model import RobotModel


def parse_floats(text: str, where: str, count: int | None = None) -> np.ndarray:
    """Comma-separated numbers -> float array; errors name ``where`` and the bad item.

    An empty text or an empty item (``0,,30``, a trailing comma) is refused: it is
    a typo, and dropping it (or falling back to a default) would be a silent guess.
    """
    import numpy as np

    if not text.strip():
        raise InputError("empty value: expected "
                         + (f"{count} " if count is not None else "")
                         + "comma-separated numbers", where=where)
    items = [s.strip() for s in text.replace(";", ",").split(",")]
    values = []
    for pos, item in enumerate(items, start=1):
        if not item:
            raise InputError(f"item {pos} is empty (two commas in a row, or a comma at an "
                             "end)", where=where)
        try:
            value = float(item)
        except ValueError:
            raise InputError(f"item {pos} ({item!r}) is not a number", where=where) from None
        if not math.isfinite(value):
            raise InputError(f"item {pos} ({item!r}) is not a finite number", where=where)
        values.append(value)
    if count is not None and len(values) != count:
        raise InputError(f"expected {count} comma-separated numbers, got {len(values)}",
                         where=where)
    return np.array(values, dtype=float)


TOOL_XYZ_HELP = ("Tool point P in the flange frame: x,y,z in mm (as the protocol's [tool] "
                 "xyz_mm); default the flange centre.")
TOOL_RPY_HELP = ("Orientation of the tool frame at P relative to the flange: roll,pitch,yaw "
                 "in deg (as the protocol's [tool] rpy_deg); default 0,0,0.")


@dataclass(frozen=True)
class ToolPoint:
    """The tool point P relative to the flange, in the protocol's units, and where it came from.

    xyz_mm : (3,) position of P in the flange frame (mm).
    rpy_deg : (3,) roll, pitch, yaw of the tool frame relative to the flange (deg).
    source : where the values came from, e.g. "--tool-xyz-mm/--tool-rpy-deg",
        "protocol [tool]", "tests.meta.json", or "none given: flange centre assumed".
    """

    xyz_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    source: str = "none given: flange centre assumed"

    @property
    def is_flange(self) -> bool:
        return not any(self.xyz_mm) and not any(self.rpy_deg)

    def describe(self) -> dict:
        """JSON-ready record (mm, deg)."""
        return {"xyz_mm": list(self.xyz_mm), "rpy_deg": list(self.rpy_deg),
                "frame": "flange", "source": self.source}

    def text(self) -> str:
        return (f"P at xyz {list(self.xyz_mm)} mm, rpy {list(self.rpy_deg)} deg in the flange "
                f"frame ({self.source})")


def tool_option(xyz_text: str | None, rpy_text: str | None,
                default: ToolPoint | None = None) -> ToolPoint:
    """``--tool-xyz-mm``/``--tool-rpy-deg`` as a :class:`ToolPoint`.

    An option not given keeps ``default``'s value (a protocol's or a sidecar's
    tool); with neither, P is the flange centre and the source says so.
    """
    base = default or ToolPoint()
    if xyz_text is None and rpy_text is None:
        return base
    xyz = base.xyz_mm if xyz_text is None else tuple(
        float(v) for v in parse_floats(xyz_text, "--tool-xyz-mm", 3))
    rpy = base.rpy_deg if rpy_text is None else tuple(
        float(v) for v in parse_floats(rpy_text, "--tool-rpy-deg", 3))
    given = [o for o, t in (("--tool-xyz-mm", xyz_text), ("--tool-rpy-deg", rpy_text)) if t]
    source = "/".join(given)
    if default is not None and len(given) < 2:
        source += f" (rest from {default.source})"
    return ToolPoint(xyz, rpy, source)


def apply_tool(robot: RobotModel, tool: ToolPoint) -> RobotModel:
    """``robot`` with P moved to ``tool`` (see :func:`analysis.model.robots.with_tool`)."""
    import numpy as np

    from analysis.model.robots import with_tool

    return with_tool(robot, np.asarray(tool.xyz_mm) * 1e-3, np.radians(tool.rpy_deg))


def robot_and_tool(robot: str, tip: str | None, tool_xyz_mm: str | None = None,
                   tool_rpy_deg: str | None = None, default_tool: ToolPoint | None = None):
    """(RobotModel with P at the tool, :class:`ToolPoint`) of the robot and tool options.

    ``default_tool`` (e.g. from a tests.meta.json sidecar) fills what the
    options do not give.
    """
    from analysis.model.robots import load_robot

    model = load_robot(robot, tip)
    tool = tool_option(tool_xyz_mm, tool_rpy_deg, default_tool)
    if tool.is_flange:
        return model, file_tool_point(model) or tool
    return apply_tool(model, tool), tool


def file_tool_point(robot: RobotModel) -> ToolPoint | None:
    """The robot file's own ``[tool]`` as a :class:`ToolPoint`, or None when P is the flange."""
    import numpy as np

    from analysis.model.robots import tool_in_flange, tool_mm_deg

    t = tool_in_flange(robot)
    if t is None or np.allclose(t, np.eye(4), atol=1e-12):
        return None
    xyz, rpy = tool_mm_deg(t)
    return ToolPoint(tuple(xyz), tuple(rpy),
                     f"tool of the robot file {robot.source_file or robot.name}")


def robot_option(robot: str, tip: str | None, tool_xyz_mm: str | None = None,
                 tool_rpy_deg: str | None = None) -> RobotModel:
    """Resolve ``--robot``/``--tip`` (built-in name, robot file or URDF) and the tool options.

    ``tool_xyz_mm``/``tool_rpy_deg`` are the texts of ``--tool-xyz-mm`` and
    ``--tool-rpy-deg``; without them P is the model's tip (the flange centre).
    """
    return robot_and_tool(robot, tip, tool_xyz_mm, tool_rpy_deg)[0]


def joint_angles_option(robot: RobotModel, text: str, controller: bool, where: str = "--q"):
    """Joint angles typed in degrees -> model-convention radians.

    With ``controller`` the angles are the teach pendant's and are converted
    with the model's offsets.
    """
    import numpy as np

    q = np.radians(parse_floats(text, where, robot.n))
    return robot.from_controller(q) if controller else q


def stiffness_option(robot: RobotModel, text: str | None) -> np.ndarray:
    """``--joint-stiffness`` (N m/rad, comma-separated) or the model's nominal values."""
    import numpy as np

    if text is not None:
        k = parse_floats(text, "--joint-stiffness", robot.n)
        if np.any(k <= 0):
            raise InputError("joint stiffness values must be positive (N m/rad)",
                             where="--joint-stiffness")
        return k
    if robot.nominal_stiffness is None:
        raise InputError(
            f"{robot.name} has no published joint stiffness: give --joint-stiffness "
            "k1,...,k6 in N m/rad",
            where="--joint-stiffness",
        )
    return robot.nominal_stiffness


def wrench_option(text: str | None, default: np.ndarray) -> np.ndarray:
    """``--wrench fx,fy,fz,mx,my,mz`` in N and N m (base frame, at P)."""
    return default.copy() if text is None else parse_floats(text, "--wrench", 6)


def numbers_option(text: str | None, where: str) -> list[float] | None:
    """A comma-separated option as typed, for a job's options record (None when not given).

    The count is checked by the job, which knows the robot (an empty text stays
    empty so that the job's message names the count expected).
    """
    if text is None:
        return None
    return [] if not text.strip() else parse_floats(text, where).tolist()
