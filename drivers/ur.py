"""Universal Robots controller through the ``ur-rtde`` library (RTDE on TCP 30004).

Receive side: ``rtde_receive.RTDEReceiveInterface(host, frequency, variables)``
with ``getActualQ()`` (rad) and ``getActualTCPPose()`` ([x, y, z] m and a
rotation vector in rad), see the ur-rtde API reference (sdurobotics.gitlab.io/ur_rtde).
The library always connects to port 30004, so the address has no port.
Control side: ``rtde_control.RTDEControlInterface(host)`` with its default
flags (``FLAG_UPLOAD_SCRIPT``): it asks the dashboard server (29999), uploads
its URScript control program to port 30003 and then sends commands through RTDE
input registers, so it is created only when a motion is first asked for.
A motion is ``moveJ(q, speed, acceleration, asynchronous=True)`` (rad/s,
rad/s^2), capped first to the address options ``max_speed`` and
``max_acceleration`` with :func:`drivers.safety.cap_motion`; the driver then
watches the receive side until the joints stand at the target (within
``tolerance`` rad, joint speeds below 1e-3 rad/s). Asynchronous, because a
synchronous ``moveJ`` cannot be interrupted (``stopJ`` waits for the control
program to be ready) and, on a lost connection, ur-rtde 1.6.5 returns True
without the robot at the target. :meth:`URRobot.stop` (from another thread
during ``move_joints``) is ``stopJ(2.0)``; the waiting ``move_joints`` then
raises :class:`DeviceFault`.

The library blocks in C++ while connecting; the driver first probes the port
from Python with a timeout so an absent controller gives :class:`ConnectionFailed`
rather than a long hang. Calls into the control interface run in a worker thread
(ur-rtde releases the GIL in them) and are abandoned after a timeout, so a
controller that stops answering gives :class:`DeviceTimeout`, not a hang.
Both interfaces can be replaced by factories (for a test double of the control
side, see ``tests/drivers``); ``tests/drivers/test_ur_control_fake.py`` runs the
real client against the fake controller of :mod:`drivers.sim.fake_rtde`.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout
from drivers.frames import pose_from_xyz_rotvec
from drivers.readings import Pose
from drivers.roles import RobotController
from drivers.safety import cap_motion

RTDE_PORT = 30004
VARIABLES = ["timestamp", "actual_q", "actual_qd", "actual_TCP_pose"]
#: limits ur-rtde itself accepts for moveJ (rad/s, rad/s^2)
UR_MAX_SPEED = 3.14
UR_MAX_ACCELERATION = 40.0
STANDSTILL = 1e-3  # rad/s


def motion_time(distance: float, speed: float, acceleration: float) -> float:
    """Duration (s) of a trapezoidal (or triangular) move over ``distance`` (rad)."""
    if distance <= 0:
        return 0.0
    if distance >= speed**2 / acceleration:
        return distance / speed + speed / acceleration
    return 2 * math.sqrt(distance / acceleration)


def call_bounded(fn: Callable[..., Any], *args: Any, timeout: float, what: str) -> Any:
    """Run ``fn(*args)`` in a daemon thread; :class:`DeviceTimeout` if it takes over ``timeout``.

    ur-rtde releases the GIL in its calls, so a blocked call cannot freeze the
    caller; on timeout the thread is left behind (it ends when the library
    gives up). A ``RuntimeError`` of the library is re-raised here.
    """
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["value"] = fn(*args)
        except Exception as err:  # handed to the caller below
            box["error"] = err

    worker = threading.Thread(target=run, daemon=True, name=f"ur-rtde {what}")
    worker.start()
    worker.join(timeout)
    if worker.is_alive():
        raise DeviceTimeout(f"ur-rtde {what} did not return within {timeout:.1f} s")
    if "error" in box:
        raise box["error"]
    return box.get("value")


def _default_receive(host: str, frequency: float) -> Any:
    import rtde_receive

    return rtde_receive.RTDEReceiveInterface(host, frequency, VARIABLES)


def _default_control(host: str) -> Any:
    import rtde_control

    return rtde_control.RTDEControlInterface(host)


class URRobot(RobotController):
    """UR robot (CB3 or e-Series) via ur-rtde.

    Parameters
    ----------
    address : str
        ``ur://host``; options ``frequency`` (Hz, default 125), ``max_speed``
        (rad/s, default 1.05) and ``max_acceleration`` (rad/s^2, default 1.4)
        capping every motion, ``tolerance`` (rad, default 1e-3) for "at the
        target", ``motion_timeout`` (s, default: 10 times the planned duration
        plus 10 s).
    receive_factory, control_factory : callable, optional
        ``receive_factory(host, frequency)`` and ``control_factory(host)``
        returning objects with the ur-rtde methods used here.
    """

    def __init__(self, address: str, *, timeout: float = 2.0,
                 receive_factory: Callable[[str, float], Any] | None = None,
                 control_factory: Callable[[str], Any] | None = None, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address)
        if addr.scheme not in ("ur", "tcp"):
            raise ConnectionFailed(f"{address!r}: expected ur://host")
        self.host = addr.host
        self.frequency = addr.float_option("frequency", 125.0)
        self.max_speed = addr.float_option("max_speed", 1.05)
        self.max_acceleration = addr.float_option("max_acceleration", 1.4)
        if not (0 < self.max_speed <= UR_MAX_SPEED and 0 < self.max_acceleration
                <= UR_MAX_ACCELERATION):
            raise ConnectionFailed(f"{address!r}: max_speed must be in (0, {UR_MAX_SPEED}] rad/s "
                                   f"and max_acceleration in (0, {UR_MAX_ACCELERATION}] rad/s^2")
        self.tolerance = addr.float_option("tolerance", 1e-3)
        self.motion_timeout = addr.float_option("motion_timeout", 0.0)
        self._receive_factory = receive_factory or _default_receive
        self._control_factory = control_factory or _default_control
        self._rx = None
        self._ctrl = None
        self._abandoned: list[Any] = []  # control interfaces with a call still blocked
        self._stopped = threading.Event()  # set by stop() to end a move_joints wait
        self._stamp = (-1.0, 0.0)

    def _connect(self) -> None:
        try:
            with socket.create_connection((self.host, RTDE_PORT), timeout=self.timeout):
                pass
        except OSError as err:
            raise ConnectionFailed(f"{self.host}:{RTDE_PORT}: {err}") from err
        try:
            self._rx = self._receive_factory(self.host, self.frequency)
        except RuntimeError as err:
            raise ConnectionFailed(f"ur-rtde could not connect to {self.host}: {err}") from err

    def _close(self) -> None:
        if self._ctrl is not None:
            self._drop_control(stop_script=True)
        if self._rx is not None:
            try:
                self._rx.disconnect()
            except RuntimeError:
                pass
        self._rx = None

    def _drop_control(self, stop_script: bool = False) -> None:
        """Stop the control program (if asked and reachable) and disconnect the control side."""
        ctrl, self._ctrl = self._ctrl, None
        try:
            if stop_script and ctrl.isConnected():
                call_bounded(ctrl.stopScript, timeout=self.timeout + 3.0, what="stopScript")
            call_bounded(ctrl.disconnect, timeout=self.timeout + 1.0, what="disconnect")
        except (RuntimeError, DeviceTimeout):
            self._abandoned.append(ctrl)

    def _fresh(self) -> None:
        """Wait (at most ``timeout``) for a data package newer than the last one used.

        Raises if the connection is lost or the stream stopped (frozen controller).
        """
        deadline = time.monotonic() + self.timeout
        while True:
            if not self._rx.isConnected():
                raise ConnectionFailed(f"{self.host}: RTDE connection lost")
            stamp = float(self._rx.getTimestamp())
            if stamp != self._stamp[0]:
                self._stamp = (stamp, time.monotonic())
                return
            if time.monotonic() > deadline:
                raise DeviceTimeout(f"{self.host}: RTDE data not updated for {self.timeout} s")
            time.sleep(0.5 / self.frequency)

    def _read_joints(self) -> np.ndarray:
        if self._rx is None:
            raise ConnectionFailed("not connected")
        self._fresh()
        return np.asarray(self._rx.getActualQ(), dtype=float)

    def _read_tool_pose(self) -> Pose | None:
        if self._rx is None:
            raise ConnectionFailed("not connected")
        self._fresh()
        v = np.asarray(self._rx.getActualTCPPose(), dtype=float)
        if v.shape != (6,) or not np.all(np.isfinite(v)):
            raise DeviceFault(f"invalid TCP pose {v!r}")
        return Pose(value=pose_from_xyz_rotvec(v), frame="base", child="tcp",
                    source=self.address)

    def _control(self) -> Any:
        if self._ctrl is None:
            try:
                self._ctrl = self._control_factory(self.host)
            except RuntimeError as err:
                raise ConnectionFailed(f"ur-rtde control to {self.host}: {err}") from err
        return self._ctrl

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        speed, acceleration = cap_motion(speed, acceleration, self.max_speed,
                                         self.max_acceleration)
        if self._rx is None:
            raise ConnectionFailed("not connected")
        self._fresh()
        distance = float(np.max(np.abs(q - np.asarray(self._rx.getActualQ(), dtype=float))))
        ctrl = self._control()
        self._stopped.clear()
        try:
            ok = call_bounded(ctrl.moveJ, [float(v) for v in q], speed, acceleration, True,
                              timeout=self.timeout + 3.0, what="moveJ")
        except DeviceTimeout:
            self._ctrl = None
            self._abandoned.append(ctrl)
            raise
        except RuntimeError as err:
            raise DeviceFault(f"moveJ failed: {err}") from err
        if not ok:
            self._drop_control()  # the control program has stopped; a new one is uploaded next time
            raise DeviceFault("controller refused or aborted moveJ (protective stop?)")
        limit = self.motion_timeout or 10 * motion_time(distance, speed, acceleration) + 10.0
        try:
            self._wait_at_target(q, time.monotonic() + limit)
        except DeviceTimeout:
            self._stop()
            raise

    def _wait_at_target(self, q: np.ndarray, deadline: float) -> None:
        """Poll the receive side until the robot stands at ``q``; raise on loss, stop or timeout."""
        ctrl = self._ctrl
        while True:
            self._fresh()
            err = float(np.max(np.abs(np.asarray(self._rx.getActualQ(), dtype=float) - q)))
            still = float(np.max(np.abs(np.asarray(self._rx.getActualQd(), dtype=float))))
            if err <= self.tolerance and still < STANDSTILL:
                return
            if self._stopped.is_set():
                raise DeviceFault(f"moveJ interrupted by stop(), {err:.2e} rad from the target")
            if ctrl is not None and not ctrl.isConnected():
                self._ctrl = None
                self._abandoned.append(ctrl)
                raise ConnectionFailed(f"{self.host}: RTDE control connection lost during moveJ")
            if ctrl is not None and not ctrl.isProgramRunning():
                self._drop_control()
                raise DeviceFault(f"control program stopped during moveJ, "
                                  f"{err:.2e} rad from the target")
            if time.monotonic() > deadline:
                raise DeviceTimeout(f"{self.host}: robot not at the target in time "
                                    f"({err:.2e} rad off)")

    def _stop(self) -> None:
        try:
            if self._ctrl is not None and self._ctrl.isConnected():
                # synchronous: returns once the robot has braked to rest
                call_bounded(self._ctrl.stopJ, 2.0, timeout=self.timeout + 3.0, what="stopJ")
        except RuntimeError as err:
            raise DeviceFault(f"stopJ failed: {err}") from err
        finally:
            self._stopped.set()

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(protocol="RTDE (ur-rtde)", frequency_hz=self.frequency,
                 max_speed_rad_s=self.max_speed, max_acceleration_rad_s2=self.max_acceleration,
                 tool_pose="x y z (m) + rotation vector (rad), base frame")
        return d
