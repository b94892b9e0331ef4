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
from campaign.planning.plan_output import MAX_REPEATS
from campaign.protocol import DEG, Protocol
from drivers.errors import SafetyRefusal
from drivers.safety import check_force, check_joint_targets, format_motion_list

Q_MODEL = [f"q{j}_model_deg" for j in range(1, 7)]
Q_CTRL = [f"q{j}_ctrl_deg" for j in range(1, 7)]
#: largest accepted difference (deg) between a pendant angle and its converted model angle
PENDANT_TOLERANCE_DEG = 0.01
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
    preload : float
        The load case's ``preload_fraction``: the reference readings are taken under
        ``preload x wrench`` (0: unloaded).
    """

    test_id: int
    pose: str
    q: np.ndarray
    q_approach: np.ndarray
    wrench: np.ndarray
    load_case: str
    repeats: int
    preload: float = 0.0


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
        limits, a bad or duplicated test id, repeats that are not a whole number
        from 1 to ``MAX_REPEATS``, controller (pendant) columns that are not the
        model columns converted (message names the test and row).
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
        q_ctrl = plan[Q_CTRL].to_numpy(dtype=float) * DEG
        w = plan[W_PLAN].to_numpy(dtype=float)
        repeats = plan["repeats"].to_numpy(dtype=float)
    except (ValueError, TypeError) as err:
        raise InputError(f"non-numeric angles, wrench or repeats: {err}", where=where) from err
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(w))):
        raise InputError("angles and wrench must be finite numbers", where=where)
    try:
        check_joint_targets(q, robot.lower, robot.upper, margin)
    except SafetyRefusal as err:
        raise InputError(f"refused before any motion: {err} (plan row = pose number; test "
                         f"{_row_test(err, ids)})", where=where) from None
    _check_pendant_columns(q, q_ctrl, robot, ids, where)
    tests = []
    preload = {c.name: c.preload_fraction for c in protocol.load_cases}
    for i, row in enumerate(plan.itertuples(index=False)):
        label = f"test {row.test}"
        if not (1 <= repeats[i] <= MAX_REPEATS and repeats[i] == int(repeats[i])):
            raise InputError(f"{label}: repeats {repeats[i]:g} is not a whole number from 1 "
                             f"to {MAX_REPEATS}", where=where)
        try:
            check_force(w[i], safety.max_force_N, safety.max_moment_N_m)
        except SafetyRefusal as err:
            raise InputError(f"{label}: refused before any motion: {err}", where=where) from None
        try:
            qa = approach_pose(robot, q[i], safety.approach_offset_mm * 1e-3, margin)
        except ValueError as err:
            raise InputError(f"{label}: refused before any motion: {err}", where=where) from None
        tests.append(PlannedTest(int(row.test), str(row.pose), q[i], qa, w[i],
                                 str(row.load_case), int(repeats[i]),
                                 preload.get(str(row.load_case), 0.0)))
    return tests


def _check_pendant_columns(q: np.ndarray, q_ctrl: np.ndarray, robot: RobotModel,
                           ids: np.ndarray, where: str) -> None:
    """Refuse a plan whose controller (pendant) angles are not its model angles converted.

    The robot is driven from the model angles; the controller columns are what the
    operator compares with the pendant, so the two must describe the same pose.
    """
    expected = np.atleast_2d(robot.to_controller(q))
    # plan.csv keeps 3 decimals (0.0005 deg of rounding on each column)
    diff = np.abs(np.rad2deg(expected - q_ctrl))
    bad = diff > PENDANT_TOLERANCE_DEG
    if bad.any():
        i, j = (int(v) for v in np.argwhere(bad)[0])
        raise InputError(
            f"line {i + 2} (test {ids[i]}), column {Q_CTRL[j]}: "
            f"{np.rad2deg(q_ctrl[i, j]):.3f} deg, but {Q_MODEL[j]} = "
            f"{np.rad2deg(q[i, j]):.3f} deg is {np.rad2deg(expected[i, j]):.3f} deg in the "
            "controller convention: the pendant and model columns disagree (edited plan, or "
            "a plan of another robot); re-plan", where=where)


def _row_test(err: SafetyRefusal, ids: np.ndarray) -> str:
    text = str(err)
    try:
        row = int(text.split("pose ", 1)[1].split(",", 1)[0]) - 1
        return str(ids[row])
    except (IndexError, ValueError):
        return "?"


def move_time(d: np.ndarray, speed: float, acceleration: float) -> np.ndarray:
    """Time (s) of joint moves of largest joint distance ``d`` (rad), trapezoidal profile.

    Each move accelerates at ``acceleration`` (rad/s^2) up to ``speed`` (rad/s),
    cruises, and brakes; a short move never reaches the speed (triangular profile).
    """
    d = np.abs(np.asarray(d, dtype=float))
    ramp = speed**2 / acceleration  # distance of the speed-up plus the slow-down
    return np.where(d >= ramp, d / speed + speed / acceleration,
                    2.0 * np.sqrt(d / acceleration))


def planned_duration(tests: list[PlannedTest], done: set[tuple[int, int]], motion: Motion,
                     settle_s: float) -> tuple[int, float, float]:
    """(measurements left, motion time (s), settling time (s)) of the rest of a run.

    Motion: approach pose then test pose for every measurement, in the order run,
    at the capped speed and acceleration (the slowest joint sets each move's time).
    Settling: three waits per measurement (before, loaded, after) of at least
    ``settle_s`` each. Taring, readings and the load handling come on top.
    """
    done_per_test: dict[int, int] = {}
    for tid, _ in done:
        done_per_test[tid] = done_per_test.get(tid, 0) + 1
    counts = [max(t.repeats - done_per_test.get(t.test_id, 0), 0) for t in tests]
    n = int(sum(counts))
    if n == 0:
        return 0, 0.0, 0.0
    # targets of one measurement: approach, then test pose; repeats follow each other
    pair = np.stack([np.stack([t.q_approach, t.q]) for t in tests])  # (tests, 2, 6)
    seq = np.repeat(pair, counts, axis=0).reshape(-1, pair.shape[-1])
    steps = np.max(np.abs(np.diff(seq, axis=0)), axis=1)
    t_motion = float(np.sum(move_time(steps, motion.speed, motion.acceleration)))
    return n, t_motion, 3.0 * n * settle_s


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 2 * 3600:
        return f"{seconds:.0f} s = {seconds / 60:.0f} min"
    return f"{seconds:.0f} s = {seconds / 3600:.1f} h"


def dry_run_text(tests: list[PlannedTest], robot: RobotModel, protocol: Protocol,
                 done: set[tuple[int, int]] | None = None, settle_s: float = 0.0) -> str:
    """The motion list shown before confirmation: every target in controller degrees,
    and the planned duration (at least: motions and settling, see :func:`planned_duration`).
    """
    done = done or set()
    motion = motion_limits(protocol)
    n_left, t_motion, t_settle = planned_duration(tests, done, motion, settle_s)
    done_ids = {tid for tid, _ in done}
    targets, labels = [], []
    for t in tests:
        finished = t.test_id in done_ids and all(
            (t.test_id, r) in done for r in range(1, t.repeats + 1))
        if finished:
            continue
        targets += [robot.to_controller(t.q_approach), robot.to_controller(t.q)]
        labels += [f"{t.test_id}a", f"{t.test_id}"]
    s = protocol.safety
    head = [
        f"robot {robot.name}: {len(labels) // 2} tests to run "
        f"({n_left} measurements), each via its approach "
        f"pose ('a', {s.approach_offset_mm:g} mm away)",
        f"planned duration: at least {_duration(t_motion + t_settle)} of robot time "
        f"({_duration(t_motion)} of motion at the limits below, {_duration(t_settle)} of "
        "settling), plus taring, readings and load handling",
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
