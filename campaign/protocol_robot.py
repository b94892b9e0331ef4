"""The robot of a protocol: model resolved, tool applied, zones and sampling boxes in SI.

Joint angles are in rad, model convention (the convention of the robot file's
zones; for the KR240-2 that of Dumas et al. 2011).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from analysis.model.robot_model import RobotModel
from analysis.model.robots import builtin_files, load_robot, with_tool
from campaign.protocol import DEG, Protocol


@dataclass(frozen=True)
class SamplingBox:
    """Where candidate poses of one zone are drawn (rad, model convention).

    ``lo[j] == hi[j]`` for a fixed joint.
    """

    name: str
    lo: np.ndarray
    hi: np.ndarray


def protocol_robot(protocol: Protocol, tool: tuple | None = None) -> RobotModel:
    """Load the protocol's robot (built-in name, or file relative to the protocol) with its tool.

    ``tool`` (xyz in m, rpy in rad) replaces the protocol's ``[tool]`` (an
    analysis that overrides it with --tool-xyz-mm/--tool-rpy-deg).
    """
    spec = protocol.campaign.robot
    if spec.strip().lower() not in builtin_files():
        candidate = Path(spec)
        if not candidate.is_absolute():
            candidate = Path(protocol.path).parent / candidate
        spec = str(candidate)
    try:
        robot = load_robot(spec)
    except InputError as err:
        raise InputError(str(err), where=protocol.where("campaign", "robot")) from None
    if robot.n != 6:
        raise InputError(f"expected a six-joint robot, got {robot.n} joints",
                         where=protocol.where("campaign", "robot"))
    if tool is not None:
        return with_tool(robot, np.asarray(tool[0], float), np.asarray(tool[1], float))
    spec = protocol.tool
    return with_tool(robot, np.array(spec.xyz_mm) * 1e-3, np.array(spec.rpy_deg) * DEG)


def prior_stiffness(protocol: Protocol, robot: RobotModel) -> np.ndarray:
    """Prior joint stiffness k0 (n,) (N m/rad): the protocol's, else the robot file's."""
    if protocol.campaign.prior_stiffness is not None:
        return np.array(protocol.campaign.prior_stiffness, dtype=float)
    if robot.nominal_stiffness is not None:
        return np.asarray(robot.nominal_stiffness, dtype=float)
    raise InputError(
        f"{robot.name} has no nominal joint stiffness: add prior_stiffness (six values, "
        "N m/rad) to [campaign]; the planner needs an order of magnitude",
        where=protocol.where("campaign"),
    )


def _joint(key: str) -> int:
    return int(key[1:]) - 1


def _inside(lo: float, hi: float, robot: RobotModel, j: int) -> bool:
    tol = 1e-9
    return lo >= robot.lower[j] - tol and hi <= robot.upper[j] + tol


def _limits_deg(robot: RobotModel, j: int) -> str:
    return f"[{robot.lower[j] / DEG:.6g}, {robot.upper[j] / DEG:.6g}] deg"


def sampling_boxes(protocol: Protocol, robot: RobotModel) -> list[SamplingBox]:
    """One box per zone, in rad: zone ranges, then fixed values, then ranges, then limits.

    Raises
    ------
    InputError
        A zone range, fixed value or range outside the joint limits (naming the
        key and line), or no zone at all.
    """
    margin = protocol.safety.joint_margin_deg * DEG
    sampling = protocol.sampling
    base_lo = robot.lower + margin
    base_hi = robot.upper - margin
    if np.any(base_lo > base_hi):
        raise InputError("the joint margin leaves no room inside the joint limits",
                         where=protocol.where("safety", "joint_margin_deg"))
    base_lo, base_hi = base_lo.copy(), base_hi.copy()
    for key, value in sampling.fixed_deg.items():
        j = _joint(key)
        v = value * DEG
        if not robot.lower[j] + margin - 1e-12 <= v <= robot.upper[j] - margin + 1e-12:
            raise InputError(
                f"{key} = {value:g} deg is outside the joint limits {_limits_deg(robot, j)} "
                f"less the {protocol.safety.joint_margin_deg:g} deg margin",
                where=protocol.where("sampling", "fixed_deg", key),
            )
        base_lo[j] = base_hi[j] = v
    for key, (lo, hi) in sampling.ranges_deg.items():
        j = _joint(key)
        if key in sampling.fixed_deg:
            raise InputError(f"{key} is both fixed and ranged",
                             where=protocol.where("sampling", "ranges_deg", key))
        if not _inside(lo * DEG, hi * DEG, robot, j):
            raise InputError(
                f"{key} range [{lo:g}, {hi:g}] deg is outside the joint limits "
                f"{_limits_deg(robot, j)}", where=protocol.where("sampling", "ranges_deg", key),
            )
        base_lo[j], base_hi[j] = lo * DEG, hi * DEG

    zones: list[tuple[str, dict[int, tuple[float, float]], str]] = []
    for i, z in enumerate(protocol.zones):
        ranges = {_joint(k): (lo * DEG, hi * DEG) for k, (lo, hi) in z.ranges_deg.items()}
        for key, (lo, hi) in z.ranges_deg.items():
            j = _joint(key)
            if not _inside(lo * DEG, hi * DEG, robot, j):
                raise InputError(
                    f"zone {z.name!r}: {key} range [{lo:g}, {hi:g}] deg is outside the joint "
                    f"limits {_limits_deg(robot, j)} (model convention)",
                    where=protocol.where("zones", i, "ranges_deg", key),
                )
        zones.append((z.name, ranges, ""))
    if not zones and sampling.use_robot_zones:
        for z in robot.zones:
            for j, (lo, hi) in z.ranges.items():
                if not _inside(lo, hi, robot, j):
                    raise InputError(
                        f"zone {z.name!r} of the robot file: q{j + 1} range "
                        f"[{lo / DEG:g}, {hi / DEG:g}] deg is outside the joint limits "
                        f"{_limits_deg(robot, j)}", where=protocol.where("campaign", "robot"),
                    )
            zones.append((z.name, dict(z.ranges), ""))
    if not zones:
        raise InputError(
            f"no zones: {robot.name} has none in its robot file; add [[zones]] with ranges_deg",
            where=protocol.where("sampling", "use_robot_zones")
            if "use_robot_zones" in protocol.text else protocol.path,
        )
    boxes = []
    for name, ranges, _ in zones:
        lo, hi = base_lo.copy(), base_hi.copy()
        for j, (a, b) in ranges.items():
            lo[j], hi[j] = max(a, robot.lower[j] + margin), min(b, robot.upper[j] - margin)
        if np.any(lo > hi):
            raise InputError(f"zone {name!r} is narrower than the joint margins",
                             where=protocol.where("safety", "joint_margin_deg"))
        boxes.append(SamplingBox(name, lo, hi))
    return boxes


def characteristic_length(protocol: Protocol, robot: RobotModel) -> float:
    """L (m) for J_N: the protocol's, else the robot file's, else computed (Khan-Angeles)."""
    if protocol.campaign.characteristic_length_mm is not None:
        return protocol.campaign.characteristic_length_mm * 1e-3
    if robot.characteristic_length is not None:
        return float(robot.characteristic_length)
    from analysis.kinetostatics.dexterity import characteristic_length as compute

    length = compute(robot, starts=4, seed=0)[0]
    return float(round(length, 4)) if math.isfinite(length) else 1.0
