"""FANUC R-30iB Plus robot through the Remote Motion Interface (RMI, option R912).

Wire format in :mod:`drivers.rmi`. ``connect()`` asks port 16001 for the session
port (``FRC_Connect``), opens it, reads ``FRC_GetStatus`` (an RMI program left running
is aborted first), clears a pending error (``FRC_Reset``), then ``FRC_Initialize``
starts the controller's RMI program and the instruction sequence at
``NextSequenceID``. A motion is one ``FRC_JointMotionJRep`` (joint representation,
``SpeedType`` ``Percent`` of the joint speed maxima, ``TermType`` ``FINE``) whose
answer arrives when the robot stands at the target; the driver waits for it
(``motion_timeout``), aborts on timeout, and checks the angles read back with
``FRC_ReadJointAngles``. :meth:`stop` is ``FRC_Abort``. ``read_tool_pose`` is
``FRC_ReadCartesianPosition`` (the active UTOOL in the active UFRAME; not used by the
analysis, which works from joint angles). Every non-zero ``ErrorID`` becomes a
:class:`DeviceFault` naming the RMIT code and the controller's text
(``FRC_ReadError``). After a late or missing answer the session is closed (a late
packet is never taken as the answer to the next request) and the next call opens a
new one.

Joint angles are in rad in the API and degrees on the wire, both in the controller's
convention (J3 relative to the horizontal on most FANUC arms: the robot model's
``controller_coupling`` converts).
"""

from __future__ import annotations

import socket
import time
from typing import Any

import numpy as np

from drivers import rmi
from drivers.address import parse_address
from drivers.errors import (
    AddressError,
    ConnectionFailed,
    DeviceFault,
    DeviceTimeout,
    DriverError,
    ProtocolError,
)
from drivers.readings import Pose
from drivers.roles import RobotController
from drivers.safety import check_reached


class _Link:
    """One TCP connection carrying CR LF-terminated RMI packets."""

    def __init__(self, host: str, port: int, timeout: float, where: str) -> None:
        self.where = where
        try:
            self.sock = socket.create_connection((host, port), timeout=timeout)
        except TimeoutError as err:
            raise DeviceTimeout(f"{where}: connect to port {port} timed out") from err
        except OSError as err:
            raise ConnectionFailed(f"{where}: port {port}: {err}") from err
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.buf = bytearray()

    def send(self, packet: dict[str, Any]) -> None:
        try:
            self.sock.sendall(rmi.encode(packet))
        except OSError as err:
            raise ConnectionFailed(f"{self.where}: {err}") from err

    def receive(self, timeout: float, said: float | None = None) -> dict[str, Any]:
        """The next packet within ``timeout`` (s); a timeout's message names ``said`` (s),
        the caller's whole wait, when given (not the part of it left for this packet)."""
        deadline = time.monotonic() + timeout
        said = timeout if said is None else said
        while True:
            end = self.buf.find(b"\r\n")
            if end >= 0:
                line = bytes(self.buf[:end])
                del self.buf[:end + 2]
                if line.strip():
                    return rmi.decode(line)
                continue
            if len(self.buf) > rmi.MAX_PACKET:
                raise ProtocolError(f"{self.where}: no CR LF within {rmi.MAX_PACKET} bytes")
            left = deadline - time.monotonic()
            if left <= 0:
                raise DeviceTimeout(f"{self.where}: no answer within {said:g} s")
            self.sock.settimeout(left)
            try:
                chunk = self.sock.recv(4096)
            except TimeoutError as err:
                raise DeviceTimeout(f"{self.where}: no answer within {said:g} s") from err
            except OSError as err:
                raise ConnectionFailed(f"{self.where}: {err}") from err
            if not chunk:
                raise ConnectionFailed(f"{self.where}: the controller closed the connection")
            self.buf += chunk

    def close(self) -> None:
        self.sock.close()


class FanucRMIRobot(RobotController):
    """FANUC robot via RMI.

    Parameters
    ----------
    address : str
        ``rmi://controller[:16001]``; options ``max_speed`` (rad/s for 100 %, default
        1.5), ``motion_timeout`` (s, default 120), ``group`` (motion group, default 1).
    """

    def __init__(self, address: str, *, timeout: float = 2.0, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address).with_default_port(rmi.HANDSHAKE_PORT)
        if addr.scheme != "rmi":
            raise AddressError(f"{address!r}: expected rmi://controller[:16001]")
        self.host, self.port = addr.host, int(addr.port or rmi.HANDSHAKE_PORT)
        self.max_speed = addr.float_option("max_speed", 1.5)
        self.motion_timeout = addr.float_option("motion_timeout", 120.0)
        self.group = addr.int_option("group", 1)
        self.session_port: int | None = None
        self.version = ""
        self._link: _Link | None = None
        self._seq = 1

    # --- session ----------------------------------------------------------
    def _connect(self) -> None:
        hand = _Link(self.host, self.port, self.timeout, self.address)
        try:
            hand.send({"Communication": "FRC_Connect"})
            reply = hand.receive(self.timeout)
        finally:
            hand.close()
        self._check(reply, "Communication", "FRC_Connect", text=False)
        try:
            self.session_port = int(reply["PortNumber"])
        except (KeyError, TypeError, ValueError) as err:
            raise ProtocolError(f"{self.address}: FRC_Connect answer has no PortNumber: "
                                f"{reply!r}") from err
        self.version = f"{reply.get('MajorVersion', '?')}.{reply.get('MinorVersion', '?')}"
        self._link = _Link(self.host, self.session_port, self.timeout, self.address)
        try:
            status = self.command("FRC_GetStatus")
            if status.get("RMIMotionStatus"):  # an RMI program left running: end it
                self.command("FRC_Abort")
            self.command("FRC_Reset")  # clear a pending controller error
            self.command("FRC_Initialize", GroupMask=1 << (self.group - 1))
            self._seq = int(self.command("FRC_GetStatus").get("NextSequenceID", 1))
        except BaseException:
            self._drop()
            raise

    def _drop(self) -> None:
        if self._link is not None:
            self._link.close()
            self._link = None

    def _close(self) -> None:
        if self._link is not None:
            try:
                self._link.send({"Communication": "FRC_Disconnect"})
                self._await("Communication", "FRC_Disconnect", None, self.timeout)
            except DriverError:
                pass
            self._drop()

    def _session(self) -> _Link:
        if self._link is None:
            if not self.connected:
                raise ConnectionFailed("not connected")
            self._connect()  # closed after a fault: open a new session
        return self._link

    # --- packets ----------------------------------------------------------
    def _await(self, family: str, name: str, seq: int | None, timeout: float
               ) -> dict[str, Any]:
        """The answer to ``name`` (and ``seq``); unsolicited packets become errors."""
        link = self._link
        deadline = time.monotonic() + timeout
        while True:
            packet = link.receive(max(deadline - time.monotonic(), 1e-3), said=timeout)
            fam, got = rmi.kind(packet)
            if fam == "Communication" and got == "FRC_Terminate":
                self._drop()
                raise ConnectionFailed(f"{self.address}: the controller ended the RMI "
                                       "session (FRC_Terminate)")
            if fam == "Communication" and got == "FRC_SystemFault":
                self._drop()
                raise DeviceFault(f"{self.address}: controller system fault during "
                                  f"instruction {packet.get('SequenceID')} (FRC_SystemFault)")
            if (fam, got) == (family, name) and (seq is None
                                                 or packet.get("SequenceID") == seq):
                return packet
            self._drop()
            raise ProtocolError(f"{self.address}: answer {got} "
                                f"(sequence {packet.get('SequenceID')}) does not answer "
                                f"{name}" + (f" (sequence {seq})" if seq else "")
                                + ": late packet; session closed")

    def _check(self, reply: dict[str, Any], family: str, name: str, text: bool = True
               ) -> dict[str, Any]:
        error = reply.get("ErrorID", 0)
        if not isinstance(error, int):
            raise ProtocolError(f"{self.address}: {name}: ErrorID {error!r} is not an integer")
        if error:
            detail = ""
            if text and self._link is not None:
                try:
                    self._link.send({"Command": "FRC_ReadError"})
                    err = self._await("Command", "FRC_ReadError", None, self.timeout)
                    detail = str(err.get("ErrorData", "")).strip()
                except DriverError:
                    detail = ""
            # the controller's text (ErrorData) names the code itself, e.g. "RMIT-029 ..."
            raise DeviceFault(f"{self.address}: {name} refused: "
                              f"{detail or rmi.error_name(error)} (ErrorID {error})")
        return reply

    def _exchange(self, packet: dict[str, Any], timeout: float) -> dict[str, Any]:
        link = self._session()
        family, name = rmi.kind(packet)
        try:
            link.send(packet)
            reply = self._await(family, name, packet.get("SequenceID"), timeout)
        except DeviceTimeout:
            self._drop()  # a late answer must not be read as the next one's
            raise
        except ConnectionFailed:
            self._drop()
            raise
        return self._check(reply, family, name)

    def command(self, name: str, **fields: Any) -> dict[str, Any]:
        """Send ``{"Command": name, **fields}`` and return the checked answer."""
        return self._exchange({"Command": name, **fields}, self.timeout)

    # --- role -------------------------------------------------------------
    def _read_joints(self) -> np.ndarray:
        return rmi.joint_angles(self.command("FRC_ReadJointAngles", Group=self.group))

    def _read_tool_pose(self) -> Pose | None:
        """The controller's position of the active UTOOL in the active UFRAME (m)."""
        reply = self.command("FRC_ReadCartesianPosition", Group=self.group)
        config = reply.get("Configuration") or {}
        return Pose(value=rmi.position_matrix(reply),
                    frame=f"uframe {config.get('UFrameNumber', '?')}",
                    child=f"utool {config.get('UToolNumber', '?')}", source=self.address)

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        percent = int(np.clip(np.ceil(100 * speed / self.max_speed), 1, 100))
        self._session()
        seq = self._seq
        packet = {"Instruction": "FRC_JointMotionJRep", "SequenceID": seq,
                  "JointAngle": rmi.joint_object(q), "SpeedType": "Percent",
                  "Speed": percent, "TermType": "FINE", "TermValue": 0}
        try:
            self._exchange(packet, self.motion_timeout)
        except DeviceTimeout:
            self.stop_quietly()
            raise DeviceTimeout(f"motion not finished after {self.motion_timeout} s; "
                                "stopped (FRC_Abort)") from None
        self._seq = seq + 1  # a refused instruction takes no sequence number
        check_reached(self._read_joints(), q)

    def _stop(self) -> None:
        self.command("FRC_Abort")
        self._drop()  # the aborted instruction's answer may still come: new session next

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(protocol="FANUC RMI", session_port=self.session_port,
                 rmi_version=self.version, max_speed=self.max_speed, group=self.group)
        return d
