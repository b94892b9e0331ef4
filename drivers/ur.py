"""Universal Robots controller through the ``ur-rtde`` library (RTDE on TCP 30004).

Receive side: ``rtde_receive.RTDEReceiveInterface(host, frequency, variables)``
with ``getActualQ()`` (rad) and ``getActualTCPPose()`` ([x, y, z] m and a
rotation vector in rad), see the ur-rtde API reference (sdurobotics.gitlab.io/ur_rtde).
The library always connects to port 30004, so the address has no port.
Control side: ``rtde_control.RTDEControlInterface(host)`` with
``moveJ(q, speed, acceleration)`` (rad/s, rad/s^2) and ``stopJ(a)``; it uploads
its own URScript program to the controller, so it is created only when a motion
is first asked for.

The library blocks in C++ while connecting; the driver first probes the port
from Python with a timeout so an absent controller gives :class:`ConnectionFailed`
rather than a long hang. Both interfaces can be replaced by factories (for a
test double of the control side, see ``tests/drivers``).
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout
from drivers.frames import pose_from_xyz_rotvec
from drivers.readings import Pose
from drivers.roles import RobotController

RTDE_PORT = 30004
VARIABLES = ["timestamp", "actual_q", "actual_TCP_pose"]


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
        ``ur://host``; option ``frequency`` (Hz, default 125).
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
        self._receive_factory = receive_factory or _default_receive
        self._control_factory = control_factory or _default_control
        self._rx = None
        self._ctrl = None
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
        for iface in (self._ctrl, self._rx):
            if iface is not None:
                try:
                    iface.disconnect()
                except RuntimeError:
                    pass
        self._ctrl = self._rx = None

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
        try:
            ok = self._control().moveJ([float(v) for v in q], speed, acceleration)
        except RuntimeError as err:
            raise DeviceFault(f"moveJ failed: {err}") from err
        if not ok:
            raise DeviceFault("controller refused or aborted moveJ (protective stop?)")

    def _stop(self) -> None:
        if self._ctrl is not None:
            self._ctrl.stopJ(2.0)

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(protocol="RTDE (ur-rtde)", frequency_hz=self.frequency,
                 tool_pose="x y z (m) + rotation vector (rad), base frame")
        return d
