"""Before any motion: the planned tests, their approach poses, the limits and the dry run.

Every joint target (approach and test pose) must lie inside the robot's
limits minus the protocol's ``joint_margin_deg``; every load case inside
``max_force_N``/``max_moment_N_m``; speed and acceleration are capped by the
protocol. A plan that breaks any of these is refused with an
:class:`~analysis.errors.InputError` naming the test, before anything is
connected or moved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.model.robot_model import RobotModel
from campaign.acquire.geometry import approach_pose
from campaign.protocol import DEG, Protocol
from drivers.errors import SafetyRefusal
from drivers.safety import check_force, check_joint_targets, format_motion_list

Q_MODEL = [f"q{j}_model_deg" for j in range(1, 7)]
W_PLAN = ["fx_N", "fy_N", "fz_N", "mx_N_m", "my_N_m", "mz_N_m"]


@dataclass(frozen=True)
class PlannedTest:
    """One planned test (SI): pose, approach, load case and repeats.

    Attributes
    ----------
    test_id : int
        ``test`` column of plan.csv.
    pose : str
        Pose label (tests on the same pose share it).
    q, q_approach : ndarray (6,)
        Joint angles of the test pose and of its approach pose (rad, model convention).
    wrench : ndarray (6,)
        Planned wrench [f (N); m (N m)], base frame at the tool point.
    load_case : str
        Name of the load case.
    repeats : int
        Times the test is measured.
    """

    test_id: int
    pose: str
    q: np.ndarray
    q_approach: np.ndarray
    wrench: np.ndarray
    load_case: str
    repeats: int


@dataclass(frozen=True)
class Motion:
    """Capped joint speed (rad/s) and acceleration (rad/s^2)."""

    speed: float
    acceleration: float


def motion_limits(protocol: Protocol) -> Motion:
    s = protocol.safety
    return Motion(s.max_joint_speed_deg_s * DEG, s.max_joint_acceleration_deg_s2 * DEG)


def planned_tests(protocol: Protocol, plan: pd.DataFrame, robot: RobotModel,
                  where: str = "plan.csv") -> list[PlannedTest]:
    """Planned tests with approach poses, after every safety check of the plan.

    Raises
    ------
    InputError
        A target outside the limits minus the margin, a load above the safety
        limits, a bad or duplicated test id (message names the test and row).
    """
    safety = protocol.safety
    margin = safety.joint_margin_deg * DEG
    if plan.empty:
        raise InputError("the plan has no tests", where=where)
    ids = plan["test"].to_numpy()
    if len(set(ids.tolist())) != len(ids):
        raise InputError("test ids in the plan are not unique", where=where)
    try:
        q = plan[Q_MODEL].to_numpy(dtype=float) * DEG
        w = plan[W_PLAN].to_numpy(dtype=float)
        repeats = plan["repeats"].to_numpy(dtype=int)
    except (ValueError, TypeError) as err:
        raise InputError(f"non-numeric angles, wrench or repeats: {err}", where=where) from err
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(w))):
        raise InputError("angles and wrench must be finite numbers", where=where)
    try:
        check_joint_targets(q, robot.lower, robot.upper, margin)
    except SafetyRefusal as err:
        raise InputError(f"refused before any motion: {err} (plan row = pose number; test "
                         f"{_row_test(err, ids)})", where=where) from None
    tests = []
    for i, row in enumerate(plan.itertuples(index=False)):
        label = f"test {row.test}"
        if repeats[i] < 1:
            raise InputError(f"{label}: repeats must be >= 1", where=where)
        try:
            check_force(w[i], safety.max_force_N, safety.max_moment_N_m)
        except SafetyRefusal as err:
            raise InputError(f"{label}: refused before any motion: {err}", where=where) from None
        try:
            qa = approach_pose(robot, q[i], safety.approach_offset_mm * 1e-3, margin)
        except ValueError as err:
            raise InputError(f"{label}: refused before any motion: {err}", where=where) from None
        tests.append(PlannedTest(int(row.test), str(row.pose), q[i], qa, w[i],
                                 str(row.load_case), int(repeats[i])))
    return tests


def _row_test(err: SafetyRefusal, ids: np.ndarray) -> str:
    text = str(err)
    try:
        row = int(text.split("pose ", 1)[1].split(",", 1)[0]) - 1
        return str(ids[row])
    except (IndexError, ValueError):
        return "?"


def dry_run_text(tests: list[PlannedTest], robot: RobotModel, protocol: Protocol,
                 done: set[tuple[int, int]] | None = None) -> str:
    """The motion list shown before confirmation: every target in controller degrees."""
    done = done or set()
    motion = motion_limits(protocol)
    targets, labels = [], []
    for t in tests:
        left = [r for r in range(1, t.repeats + 1) if (t.test_id, r) not in done]
        if not left:
            continue
        targets += [robot.to_controller(t.q_approach), robot.to_controller(t.q)]
        labels += [f"{t.test_id}a", f"{t.test_id}"]
    s = protocol.safety
    head = [
        f"robot {robot.name}: {len(labels) // 2} tests to run "
        f"({sum(t.repeats for t in tests) - len(done)} measurements), each via its approach "
        f"pose ('a', {s.approach_offset_mm:g} mm away)",
        f"joint limits minus {s.joint_margin_deg:g} deg checked; speed <= "
        f"{s.max_joint_speed_deg_s:g} deg/s, acceleration <= "
        f"{s.max_joint_acceleration_deg_s2:g} deg/s^2; force stop above {s.max_force_N:g} N "
        f"or {s.max_moment_N_m:g} N m",
        "joint targets, controller convention:",
    ]
    if not targets:
        return "\n".join(head[:1]) + "\nnothing left to run"
    body = format_motion_list(np.array(targets), labels, speed=motion.speed)
    return "\n".join(head) + "\n" + body
