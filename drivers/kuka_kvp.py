"""KUKA KR C4 robot through KUKAVARPROXY (TCP 7000) and the shipped KRL loop program.

The controller runs ``drivers/krl/stiff_loop.src`` (see ``drivers/krl/README.md``),
which waits for ``STIFF_GO``, moves PTP to ``STIFF_TARGET`` with ``STIFF_VEL``
and ``STIFF_ACC`` percent of the axis maxima, then clears ``STIFF_GO``. This
driver writes those globals and reads ``$AXIS_ACT`` through KUKAVARPROXY (message
format in :mod:`drivers.kvp`). ``STIFF_STOP`` triggers the program's interrupt,
which brakes the robot.

Joint angles are exchanged in degrees on the wire and in rad in the API
(controller convention, i.e. as on the teach pendant).
"""

from __future__ import annotations

import socket
import struct
import time
from typing import Any

import numpy as np

from drivers import kvp
from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, DriverError
from drivers.readings import Pose
from drivers.roles import RobotController
from drivers.tcp_link import TcpLink

KVP_PORT = 7000


class KukaVarProxyRobot(TcpLink, RobotController):
    """KUKA robot via KUKAVARPROXY.

    Parameters
    ----------
    address : str
        ``socket://controller[:7000]``; options ``max_speed`` (rad/s for 100 %,
        default 1.5), ``max_acc`` (rad/s^2 for 100 %, default 3.0),
        ``motion_timeout`` (s, default 120).
    """

    peer = "KUKAVARPROXY"

    def __init__(self, address: str, *, timeout: float = 2.0, poll: float = 0.05,
                 **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address).with_default_port(KVP_PORT)
        if addr.scheme != "tcp":
            raise ConnectionFailed(f"{address!r}: expected socket://controller:7000")
        self.host, self.port = addr.host, int(addr.port or KVP_PORT)
        self.max_speed = addr.float_option("max_speed", 1.5)
        self.max_acc = addr.float_option("max_acc", 3.0)
        self.motion_timeout = addr.float_option("motion_timeout", 120.0)
        self.poll = poll
        self._sock: socket.socket | None = None
        self._msg_id = 0

    def _exchange(self, name: str, value: str | None = None) -> str:
        if not self.connected:
            raise ConnectionFailed("not connected")
        if self._sock is None:  # dropped after an error: reconnect once
            self._connect()
        self._msg_id = (self._msg_id + 1) & 0xFFFF
        try:
            self._sock.sendall(kvp.encode_request(self._msg_id, name, value))
            head = self._recv_exact(4)
            (length,) = struct.unpack(">H", head[2:])
            return kvp.decode_reply(head, self._recv_exact(length), self._msg_id, name,
                                    read=value is None)
        except (DriverError, OSError) as err:
            self._close()  # never read a late reply as the answer to the next request
            if isinstance(err, DriverError):
                raise
            raise ConnectionFailed(f"{self.address}: {err}") from err
        except BaseException:
            # interrupted between request and reply (Ctrl-C): the reply may still come,
            # and the next request (the stop that follows) must not take it for its own
            self._close()
            raise

    def read_var(self, name: str) -> str:
        """Read a KRL variable as text."""
        return self._exchange(name)

    def write_var(self, name: str, value: str) -> None:
        """Write a KRL global variable (text value)."""
        self._exchange(name, value)

    def _read_joints(self) -> np.ndarray:
        return kvp.parse_axis(self.read_var("$AXIS_ACT"))

    def _read_tool_pose(self) -> Pose | None:
        return None  # $POS_ACT depends on the active tool/base; the analysis uses joint angles

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        vel = int(np.clip(np.ceil(100 * speed / self.max_speed), 1, 100))
        acc = int(np.clip(np.ceil(100 * acceleration / self.max_acc), 1, 100))
        self.write_var("STIFF_STOP", "FALSE")
        self.write_var("STIFF_TARGET", kvp.format_axis(q))
        self.write_var("STIFF_VEL", str(vel))
        self.write_var("STIFF_ACC", str(acc))
        self.write_var("STIFF_GO", "TRUE")
        deadline = time.monotonic() + self.motion_timeout
        while self.read_var("STIFF_GO").strip().upper() != "FALSE":
            if time.monotonic() > deadline:
                self.stop()
                raise DeviceTimeout(f"motion not finished after {self.motion_timeout} s; stopped")
            time.sleep(self.poll)
        reached = self._read_joints()
        if np.max(np.abs(reached - q)) > np.deg2rad(0.05):
            raise DeviceFault(f"robot stopped {np.rad2deg(np.max(np.abs(reached - q))):.3f} deg "
                              "away from the target")

    def _stop(self) -> None:
        self.write_var("STIFF_STOP", "TRUE")

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(protocol="KUKAVARPROXY", program="drivers/krl/stiff_loop.src",
                 max_speed=self.max_speed, max_acc=self.max_acc)
        return d
