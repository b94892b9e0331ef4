"""What the jobs share: checks of SI option values and the progress hook.

A job's options record holds numbers already parsed (SI units, radians); the
command line parses its comma-separated texts at its edge and the web API
receives lists. Both reach the checks here, so a wrong count or a non-finite
value gets the same one-line message from either face.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager

import numpy as np

from analysis.errors import InputError

#: ``stage(text)``: a context manager around one long step (the CLI draws a spinner).
Stage = Callable[[str], AbstractContextManager]


#: ``note(text)``: one line of progress the command line prints as it comes (an assumption).
Note = Callable[[str], None]


def no_note(text: str) -> None:
    """The default note hook: nothing shown (the result record holds the same facts)."""


@contextmanager
def no_stage(text: str) -> Iterator[None]:
    """The default progress hook: nothing shown."""
    yield


def floats(values: Sequence[float], where: str, count: int | None = None) -> np.ndarray:
    """``values`` as a float array; refuse a wrong count or a non-finite item naming ``where``.

    The messages are those of :func:`campaign.options.parse_floats` for the same fault.
    """
    out = []
    for pos, value in enumerate(values, start=1):
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(f"item {pos} ({value!r}) is not a number", where=where) from None
        if not math.isfinite(v):
            raise InputError(f"item {pos} ({value!r}) is not a finite number", where=where)
        out.append(v)
    if not out:
        raise InputError("empty value: expected " + (f"{count} " if count is not None else "")
                         + "comma-separated numbers", where=where)
    if count is not None and len(out) != count:
        raise InputError(f"expected {count} comma-separated numbers, got {len(out)}",
                         where=where)
    return np.array(out, dtype=float)


def joint_stiffness(robot, values: Sequence[float] | None) -> np.ndarray:
    """Joint stiffness (N m/rad) given, or the model's nominal values (as ``--joint-stiffness``)."""
    if values is not None:
        k = floats(values, "--joint-stiffness", robot.n)
        if np.any(k <= 0):
            raise InputError("joint stiffness values must be positive (N m/rad)",
                             where="--joint-stiffness")
        return k
    from campaign.options import stiffness_option

    return stiffness_option(robot, None)


def wrench(values: Sequence[float] | None, default: np.ndarray) -> np.ndarray:
    """The wrench [fx, fy, fz (N), mx, my, mz (N m)] given, or a copy of ``default``."""
    return default.copy() if values is None else floats(values, "--wrench", 6)


def robot_and_tool(robot: str, tip: str | None, tool_xyz_mm: Sequence[float] | None,
                   tool_rpy_deg: Sequence[float] | None, default_tool=None):
    """(RobotModel with P at the tool, ToolPoint) as :func:`campaign.options.robot_and_tool`.

    The tool is given as the protocol's ``[tool]`` table gives it: xyz in mm and
    roll, pitch, yaw in degrees, in the flange frame (the record the report
    prints); it is converted to SI when the model is built.
    """
    from campaign.options import robot_and_tool as _parsed

    model, tool = _parsed(robot, tip, *tool_texts(tool_xyz_mm, tool_rpy_deg), default_tool)
    six_joints(model)
    return model, tool


def six_joints(robot, where: str = "--robot") -> None:
    """Refuse a robot that is not a six-joint arm: the method (K_X = J^-T (K_theta - K_C)
    J^-1, the 1/kappa_F maps, the six-component tests) needs a square 6 x 6 Jacobian;
    ``where``: the option or field that named the robot."""
    if robot.n != 6:
        raise InputError(f"{robot.name} has {robot.n} joints: this method needs a six-joint "
                         "arm (a square 6 x 6 Jacobian)", where=where)


def tool_texts(tool_xyz_mm: Sequence[float] | None,
               tool_rpy_deg: Sequence[float] | None) -> tuple[str | None, str | None]:
    """The tool's numbers as the texts :func:`campaign.options.tool_option` reads (exact:
    ``repr`` of a float reads back the same float); counts checked here."""

    def text(values, where):
        if values is None:
            return None
        return ",".join(repr(float(v)) for v in floats(values, where, 3))

    return text(tool_xyz_mm, "--tool-xyz-mm"), text(tool_rpy_deg, "--tool-rpy-deg")
