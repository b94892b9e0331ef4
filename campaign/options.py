"""Parsing of command-line values: lists of numbers with units, robot selection."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from analysis.errors import InputError

if TYPE_CHECKING:  # the robot model pulls in pinocchio: imported when a robot is loaded
    from analysis.model.robot_model import RobotModel


def parse_floats(text: str, where: str, count: int | None = None) -> np.ndarray:
    """Comma-separated numbers -> float array; errors name ``where`` and the bad item."""
    items = [s.strip() for s in text.replace(";", ",").split(",") if s.strip()]
    values = []
    for pos, item in enumerate(items, start=1):
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


def robot_option(robot: str, tip: str | None) -> RobotModel:
    """Resolve ``--robot``/``--tip`` (built-in name, robot file or URDF)."""
    from analysis.model.robots import load_robot

    return load_robot(robot, tip)


def joint_angles_option(robot: RobotModel, text: str, controller: bool, where: str = "--q"):
    """Joint angles typed in degrees -> model-convention radians.

    With ``controller`` the angles are the teach pendant's and are converted
    with the model's offsets.
    """
    q = np.radians(parse_floats(text, where, robot.n))
    return robot.from_controller(q) if controller else q


def stiffness_option(robot: RobotModel, text: str | None) -> np.ndarray:
    """``--joint-stiffness`` (N m/rad, comma-separated) or the model's nominal values."""
    if text:
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
    return default.copy() if not text else parse_floats(text, "--wrench", 6)
