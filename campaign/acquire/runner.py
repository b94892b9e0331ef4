"""The acquisition state machine: one planned test after another, nothing lost.

For each (test, repeat) not yet in ``tests.csv``: approach pose -> test pose
-> settle -> tare -> unloaded pose -> apply load -> settle -> wrench and
loaded pose -> remove load -> settle -> unloaded pose again -> checks -> one
row appended to ``tests.csv``. Every reading is appended to ``samples.jsonl``
(fsynced) as soon as it is taken, so before the next motion.

Failures: a failed check or a device fault retries the test once (after
removing the load and reconnecting); a check failing twice gives a
``failed`` row with its flags, a fault twice stops the run (status
``failed``). A force above the protocol's limit (:class:`SafetyRefusal`)
stops at once (``aborted``), and so does Ctrl-C: motion stopped, load removed
when automated, status written.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from analysis.identification.io.columns import REF_W_COLS
from analysis.model.kinematics import rotation_vector, tool_pose
from analysis.model.robot_model import RobotModel
from campaign.acquire.checks import Limits, evaluate
from campaign.acquire.clock import WallClock, utc
from campaign.acquire.geometry import (
    base_in_tracker_rotation,
    displacement,
    loaded_tool_pose,
    mean_pose,
    sensor_wrench_to_base,
)
from campaign.acquire.instruments import Instruments
from campaign.acquire.interrupts import interrupt_reason
from campaign.acquire.preflight import Motion, PlannedTest
from campaign.acquire.progress import Reporter
from campaign.acquire.rundir import RunDir, WriteFailure, read_samples
from campaign.acquire.settle import SettleRule, wait_settled
from drivers.errors import DriverError, SafetyRefusal
from drivers.readings import Pose
from drivers.roles import LoadCase
from drivers.safety import check_force


def load_may_hang(run_path) -> bool:
    """True if events.jsonl of a run ends with a load applied and not removed."""
    import json

    state = False
    path = run_path / "events.jsonl"
    if not path.exists():
        return False
    for line in path.read_bytes().splitlines():
        try:
            kind = json.loads(line).get("event")
        except (ValueError, AttributeError):  # a damaged line, or not an object
            continue
        if kind == "load_applied":
            state = True
        elif kind == "load_removed":
            state = False
    return state


class CheckFailed(Exception):
    """A measured test failed a check; carries the row that would have been written."""

    def __init__(self, row: dict[str, Any], flags: tuple[str, ...]) -> None:
        super().__init__(", ".join(flags))
        self.row, self.flags = row, flags


@dataclass(frozen=True)
class RunSettings:
    """How readings are taken: sample counts and the settling rule."""

    settle: SettleRule
    tare_samples: int = 50
    wrench_samples: int = 100


class Runner:
    """Runs the remaining tests of a run directory with connected instruments.

    ``clock`` stamps the readings (``t_utc`` of samples.jsonl and tests.csv): the wall
    clock by default, the simulated lab's :class:`~campaign.acquire.clock.SimulatedClock`
    on ``--fake``; the events keep the wall clock.
    """

    def __init__(self, run: RunDir, robot: RobotModel, tests: list[PlannedTest],
                 inst: Instruments, reporter: Reporter, limits: Limits, motion: Motion,
                 settings: RunSettings, max_force: float, max_moment: float,
                 on_event: Callable[[dict[str, Any]], None] | None = None,
                 clock: WallClock | None = None) -> None:
        self.run_dir, self.robot, self.tests, self.inst = run, robot, tests, inst
        self.clock = clock or WallClock()
        self.reporter, self.limits, self.motion, self.settings = reporter, limits, motion, settings
        self.max_force, self.max_moment = max_force, max_moment
        self.on_event = on_event
        self.load_applied = False
        self.ctx: dict[str, Any] = {}
        self.counts = {"ok": 0, "failed": 0}
        self.first_unloaded: dict[int, np.ndarray] = {}
        #: events that could not be written while making safe (told in the final reason)
        self.unrecorded: list[str] = []
        #: why the load is still on the tool at the end, or None when it is not
        self.load_left: str | None = None

    # -- records ---------------------------------------------------------------------------
    def _sample(self, phase: str, instrument: str, quantity: str, unit: str, frame: str,
                value: Any, sigma: Any = None, wall: float | None = None, **extra: Any) -> None:
        self.run_dir.sample({
            "t_utc": self.clock.stamp(wall), "session": self.run_dir.session,
            "test_id": self.ctx.get("test_id"),
            "repeat": self.ctx.get("repeat"), "attempt": self.ctx.get("attempt"),
            "phase": phase, "instrument": instrument, "quantity": quantity, "unit": unit,
            "frame": frame, "value": np.asarray(value, dtype=float).ravel().tolist(),
            "sigma": None if sigma is None else np.asarray(sigma, float).ravel().tolist(),
            **extra})

    def _event(self, event: str, **fields: Any) -> None:
        record = {"t_utc": utc(), "event": event, "session": self.run_dir.session,
                  **{k: self.ctx.get(k) for k in ("test_id", "repeat", "attempt")}, **fields}
        self.run_dir.event(record)
        self.reporter.event(record)
        if self.on_event is not None:
            self.on_event(record)

    def _record(self, event: str, **fields: Any) -> None:
        """:meth:`_event` while making safe: a failed write must not stop the stopping.

        What could not be written is kept and told to the operator.
        """
        try:
            self._event(event, **fields)
        except WriteFailure:
            self.unrecorded.append(f"{event}: {fields.get('reason', '')}".rstrip(": "))

    def _phase(self, phase: str, **live: Any) -> None:
        self.ctx["phase"] = phase
        self.inst.mark(self.ctx.get("test_id"), self.ctx.get("repeat"), self.ctx.get("attempt"),
                       phase)
        self.run_dir.event({"t_utc": utc(), "event": "phase", "phase": phase,
                            "session": self.run_dir.session,
                            **{k: self.ctx.get(k) for k in ("test_id", "repeat", "attempt")}})
        self.reporter.phase(phase=phase, **{k: self.ctx.get(k) for k in
                                            ("test_id", "repeat", "attempt", "pose")}, **live)

    # -- resume state ----------------------------------------------------------------------
    def _recover_first_unloaded(self, done: set[tuple[int, int]]) -> None:
        """Reference tool point (unloaded, or under the test's preload) of the first
        finished repeat of each test, from samples."""
        samples = read_samples(self.run_dir.path)
        if samples.empty:
            return
        last: dict[tuple[int, int], np.ndarray] = {}
        sel = samples[(samples["quantity"] == "tool_pose")
                      & samples["phase"].isin(["unloaded_before", "reference_before"])]
        for rec in sel.itertuples(index=False):
            last[(int(rec.test_id), int(rec.repeat))] = np.asarray(rec.value[:3], dtype=float)
        for (tid, rep) in sorted(done):
            if tid not in self.first_unloaded and (tid, rep) in last:
                self.first_unloaded[tid] = last[(tid, rep)]

    # -- the run ----------------------------------------------------------------------------
    def run(self) -> tuple[str, str]:
        """Run every unfinished (test, repeat); returns (status, reason) as written."""
        done = self.run_dir.finished()
        self._recover_first_unloaded(done)
        todo = [(t, r) for t in self.tests for r in range(1, t.repeats + 1)
                if (t.test_id, r) not in done]
        total = sum(t.repeats for t in self.tests)
        self.reporter.phase(done=len(done), total=total, done_this_session=0)
        self._event("session_start", remaining=len(todo), finished=len(done))
        # anything but a finished loop leaves the robot stopped and unloaded (see finally)
        status, reason = "failed", "unexpected error"
        try:
            if todo and load_may_hang(self.run_dir.path):
                # the last session ended with a load applied: take it off before any motion
                self._phase("remove_load")
                self.inst.load.remove()
                self._event("load_removed", reason="left applied by the previous session")
            for i, (test, repeat) in enumerate(todo):
                self._run_test(test, repeat)
                self.reporter.phase(done=len(done) + i + 1, done_this_session=i + 1)
            status, reason = "complete", ""
        except SafetyRefusal as err:
            status, reason = "aborted", f"safety stop: {err}"
            self._record("abort", reason=reason)
        except DriverError as err:
            status, reason = "failed", f"device fault after a retry: {err}"
            self._record("abort", reason=reason)
        except WriteFailure as err:
            status, reason = "failed", (f"{err}; free space or fix the permissions, then "
                                        "resume the run")
            self._record("abort", reason=reason)
        except KeyboardInterrupt as err:
            status, reason = "aborted", interrupt_reason(err)
            self._record("interrupt", reason=reason)
        finally:
            self._make_safe(status)
        if self.load_left:
            reason = f"{reason}; LOAD STILL APPLIED: {self.load_left}".lstrip("; ")
        if self.unrecorded:
            reason += f"; not recorded in events.jsonl: {', '.join(self.unrecorded)}"
        extra: dict[str, Any] = {"ended_utc": utc()}
        if self.load_left:
            extra["load_left_applied"] = self.load_left
        try:
            self.run_dir.set_status(status, reason, **extra)
        except WriteFailure as err:
            reason = "; ".join(filter(None, [reason, f"metadata.json still says running "
                                                      f"({err}): resuming the run records it"]))
            # the appended files are still open: the status goes into events.jsonl at least
            self._record("status", status=status, reason=reason)
        return status, reason

    def _make_safe(self, status: str) -> None:
        """Stop motion and remove the load (if any) before the status is written.

        Every step is recorded in events.jsonl: ``robot_stopped`` (or a ``fault``
        saying the stop failed), ``load_removed``, or ``load_left`` when the load is
        still on the tool (a manual load, or a removal that failed), which is also
        shown to the operator.
        """
        main = threading.current_thread() is threading.main_thread()
        # the handler is read before and replaced inside the try: a Ctrl-C still pending
        # when SIG_IGN is set is raised right after that call, and must reach the finally
        # (else Ctrl-C would stay ignored for the rest of the process)
        old = signal.getsignal(signal.SIGINT) if main else None
        try:
            if main:
                signal.signal(signal.SIGINT, signal.SIG_IGN)
            if status != "complete":
                try:
                    self.inst.robot.stop()
                    self._record("robot_stopped")
                except (DriverError, OSError) as err:
                    self._record("fault", reason=f"could not stop the robot: {err}")
                    self.reporter.message(f"COULD NOT STOP THE ROBOT: {err}: use the "
                                          "controller's stop")
            if self.load_applied:
                if self.inst.automated_load:
                    try:
                        self.inst.load.remove()
                        self.load_applied = False
                        self._record("load_removed", reason="safe stop")
                    except (DriverError, OSError) as err:
                        self.load_left = f"could not remove the load: {err}"
                        self._record("load_left", reason=self.load_left)
                        self.reporter.message(f"THE LOAD IS STILL APPLIED ({err}): "
                                              "REMOVE IT BY HAND before anything else")
                else:
                    self.load_left = "manual load: remove it by hand"
                    self.reporter.message("REMOVE THE LOAD FROM THE TOOL by hand")
                    self._record("load_left", reason=self.load_left)
        finally:
            if main:
                signal.signal(signal.SIGINT, signal.SIG_DFL if old is None else old)

    def _run_test(self, test: PlannedTest, repeat: int) -> None:
        for attempt in (1, 2):
            self.ctx = {"test_id": test.test_id, "repeat": repeat, "attempt": attempt,
                        "pose": test.pose}
            try:
                row = self._measure(test, repeat)
                if attempt == 2:
                    row["flags"] = "retried"
            except CheckFailed as err:
                if attempt == 1:
                    self._event("retry", reason=f"check failed: {', '.join(err.flags)}")
                    continue
                row = dict(err.row, status="failed", flags=";".join([*err.flags, "retried"]))
            except SafetyRefusal:
                raise
            except DriverError as err:
                self._event("fault", reason=f"{type(err).__name__}: {err}",
                            phase=self.ctx.get("phase"))
                if attempt == 2:
                    raise
                try:
                    self._recover()
                except DriverError as again:
                    raise type(again)(f"{again} (while recovering from: {err})") from again
                self._event("retry", reason=f"device fault: {err}")
                continue
            self.run_dir.test_row(row)
            self.counts["ok" if row["status"] == "ok" else "failed"] += 1
            if row["status"] == "ok" and test.test_id not in self.first_unloaded:
                self.first_unloaded[test.test_id] = self.ctx["p_before"]
            self._event("test_done", status=row["status"], flags=row["flags"],
                        dx_mm=[row["dx_mm"], row["dy_mm"], row["dz_mm"]])
            return

    def _recover(self) -> None:
        """After a fault: remove the load (recorded), reconnect every instrument."""
        if self.load_applied:
            self.inst.load.remove()
            self.load_applied = False
            self._event("load_removed", reason="before the retry")
        self.inst.reconnect()

    # -- one measurement ---------------------------------------------------------------------
    def _move(self, q_model: np.ndarray, phase: str) -> np.ndarray:
        self._phase(phase, q_deg=np.rad2deg(q_model),
                    q_ctrl_deg=np.rad2deg(self.robot.to_controller(q_model)))
        q_ctrl = self.robot.to_controller(q_model)
        reached = self.inst.robot.move_joints(q_ctrl, self.motion.speed,
                                              self.motion.acceleration)
        self.clock.move(q_ctrl)
        self._sample(phase, "robot", "joint_angles", "rad", "controller", reached.value,
                     wall=reached.wall_time)
        return self.robot.from_controller(reached.value)

    def _settle(self, phase: str, ref: np.ndarray | None = None,
                r_base: np.ndarray | None = None) -> None:
        self._phase(phase)

        def read() -> np.ndarray:
            p = self.inst.read_point()
            self.clock.settle_read()
            self._sample(phase, "pose", "point", "m", "tracker", p)
            if ref is not None and r_base is not None:
                self.reporter.phase(deflection_mm=r_base.T @ (p - ref) * 1e3)
            return p

        self.clock.settle_start()
        wait_settled(read, self.settings.settle)
        self.clock.settle_end()

    def _pose(self, phase: str) -> Pose:
        self._phase(phase)
        pose = self.inst.tracker.measure_pose()
        T = np.asarray(pose.value, dtype=float)
        self._sample(phase, "pose", "tool_pose", "m, rad", "tracker",
                     np.concatenate([T[:3, 3], rotation_vector(T[:3, :3])]),
                     wall=pose.wall_time, residual_m=pose.residual)
        return pose

    def _measure(self, test: PlannedTest, repeat: int) -> dict[str, Any]:
        inst = self.inst
        # the previous test's readings are not this one's: blank until measured
        self.reporter.phase(wrench=None, wrench_planned=None, deflection_mm=None,
                            rotation_mrad=None)
        self._move(test.q_approach, "approach")
        q = self._move(test.q, "move")
        T_fk = tool_pose(self.robot, q)
        self._settle("settle_unloaded_before")
        self._phase("tare")
        bias = inst.ft.tare(self.settings.tare_samples)
        self.clock.wait(self.settings.tare_samples / inst.ft.rate_hz)
        self._sample("tare", "force_torque", "bias", "N, N m", "sensor", bias)
        w_ref = None
        T_ref = T_fk  # the reference reading's tool pose, base frame
        if test.preload > 0:  # the reference reading under the preload, on the load's flanks
            # the tracker's axes from the unloaded pose: the preloaded one is already turned
            # by the preload's deflection (2-5 mrad on a KR240-2 at 30 %), which taken as the
            # encoders' pose turned the displacement and both wrenches by it (k3 +0.5 %)
            Pu = self._pose("unloaded_before")
            R = base_in_tracker_rotation(Pu.value, T_fk)
            self._preload(test, "before")
            W0 = self._wrench("reference_before")
            P0 = self._pose("reference_before")
            T_ref = loaded_tool_pose(T_fk, displacement(Pu.value, P0.value, R))
            w_ref = sensor_wrench_to_base(W0.value, T_ref, inst.sensor_mount)
        else:
            P0 = self._pose("unloaded_before")
            R = base_in_tracker_rotation(P0.value, T_fk)
        ref_point = self._reflector_point(P0.value)

        self._phase("apply_load", load_case=test.load_case, wrench_planned=test.wrench)
        self.load_applied = True  # set first: a half-applied load must be removed too
        inst.load.apply(LoadCase(test.load_case, test.wrench))
        self._event("load_applied", load_case=test.load_case)
        self._settle("settle_loaded", ref_point, R)
        self._phase("loaded")
        W = inst.ft.read_wrench(self.settings.wrench_samples)
        self.clock.wait(self.settings.wrench_samples / inst.ft.rate_hz)
        # the mean is the value; every raw sample of the window is kept beside it
        raw = None if W.raw is None else np.asarray(W.raw, float).tolist()
        self._sample("loaded", "force_torque", "wrench", "N, N m", "sensor", W.value,
                     sigma=W.spread, wall=W.wall_time, samples=W.samples, raw=raw)
        w_approx = sensor_wrench_to_base(W.value, T_fk, inst.sensor_mount)
        self.reporter.phase(wrench=w_approx)
        check_force(w_approx, self.max_force, self.max_moment)
        P1 = self._pose("loaded")

        if w_ref is not None:
            self._preload(test, "after")
            P2 = self._pose("reference_after")
        self._phase("remove_load")
        inst.load.remove()
        self.load_applied = False
        self._event("load_removed")
        self._settle("settle_unloaded_after")
        if w_ref is None:
            P2 = self._pose("unloaded_after")

        ref = mean_pose(P0.value, P2.value)
        screw = displacement(ref, P1.value, R)
        w_base = sensor_wrench_to_base(W.value, loaded_tool_pose(T_ref, screw), inst.sensor_mount)
        p0, p2 = P0.value[:3, 3], P2.value[:3, 3]
        self.ctx["p_before"] = p0
        res = evaluate(self.limits, p0, p2, self.first_unloaded.get(test.test_id), w_base,
                       test.wrench, W.value, [P0.residual, P1.residual, P2.residual])
        row: dict[str, Any] = {"pose": test.pose}
        for j in range(6):
            row[f"q{j + 1}_deg"] = float(np.rad2deg(q[j]))
        for name, v in zip(["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"], w_base,
                           strict=True):
            row[name] = float(v)
        for name, v in zip(["dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"],
                           screw * 1e3, strict=True):
            row[name] = float(v)
        if w_ref is not None:
            for name, v in zip(REF_W_COLS, w_ref, strict=True):
                row[name] = float(v)
        row.update(test_id=test.test_id, repeat=repeat, status="ok", flags="",
                   repeatability_mm=res.repeatability * 1e3, drift_mm=res.drift * 1e3,
                   wrench_error_N=res.wrench_error, tracker_sigma_mm=res.tracker_sigma * 1e3,
                   t_utc=self.clock.stamp())
        self.reporter.phase(deflection_mm=screw[:3] * 1e3, rotation_mrad=screw[3:] * 1e3,
                            wrench=w_base)
        if res.flags:
            raise CheckFailed(row, res.flags)
        return row

    def _preload(self, test: PlannedTest, when: str) -> None:
        """Apply the test's preload (``preload`` x its wrench, same direction) and settle."""
        self._phase(f"apply_preload_{when}", load_case=test.load_case,
                    wrench_planned=test.preload * test.wrench)
        self.load_applied = True
        self.inst.load.apply(LoadCase(f"{test.load_case} preload", test.preload * test.wrench))
        self._event("preload_applied", load_case=test.load_case, fraction=test.preload)
        self._settle(f"settle_reference_{when}")

    def _wrench(self, phase: str):
        """A window of F/T samples (sensor frame), recorded under ``phase``."""
        self._phase(phase)
        W = self.inst.ft.read_wrench(self.settings.wrench_samples)
        self.clock.wait(self.settings.wrench_samples / self.inst.ft.rate_hz)
        raw = None if W.raw is None else np.asarray(W.raw, float).tolist()
        self._sample(phase, "force_torque", "wrench", "N, N m", "sensor", W.value,
                     sigma=W.spread, wall=W.wall_time, samples=W.samples, raw=raw)
        return W

    def _reflector_point(self, T: np.ndarray) -> np.ndarray:
        refl = self.inst.tracker.reflectors
        r = np.asarray(next(iter(refl.values())), float) if refl else np.zeros(3)
        return (np.asarray(T) @ np.append(r, 1.0))[:3]
