"""Fake FANUC RMI controller: the handshake port, then the session port it announces.

Speaks :mod:`drivers.rmi` (B-84184EN/03) over the lab's world, so any RMI client can
connect, initialize, read the joints, move and abort:

* handshake: ``FRC_Connect`` is answered with ``PortNumber`` (the session listener) and
  the connection is closed by the client; a second ``FRC_Connect`` while a session is
  open (or announced less than 2 s ago) gets RMIT-026 (*Robot is Already Connected*);
* commands ``FRC_Initialize`` (RMIT-008 when the pendant is enabled, RMIT-015 when RMI
  already runs), ``FRC_Abort``, ``FRC_Pause``/``FRC_Continue``, ``FRC_Reset``,
  ``FRC_GetStatus``, ``FRC_ReadError``, ``FRC_ReadJointAngles``,
  ``FRC_ReadCartesianPosition``, ``FRC_SetOverRide``, ``FRC_GetUFrameUTool``,
  ``FRC_SetUFrameUTool``; any other command: RMIT-013;
* instructions (RMIT-009 before ``FRC_Initialize``, RMIT-029 for a ``SequenceID`` other
  than ``NextSequenceID``): ``FRC_JointMotionJRep`` (``SpeedType`` ``Percent`` of
  ``max_speed``, times the override; ``TermType`` ``FINE`` or ``CNT``; a target outside
  the limits: RMIT-036) answered when the simulated motion ends, ``FRC_WaitTime``,
  ``FRC_SetUFrame``, ``FRC_SetUTool``; any other: RMIT-020;
* ``FRC_Disconnect`` is answered and the session closed; a packet that is not JSON
  closes it.

Joint angles are the world's (controller convention, so J3 is the coupled one for a
FANUC model); Cartesian positions are the nominal tool pose in FANUC's world frame
(UFRAME 0: the model's base frame raised to the height of J2's axis, as ROS-Industrial's
``base`` frame; mm, W-P-R in degrees: R = Rz(R) Ry(P) Rx(W)). Tests arm controller errors with
:attr:`FakeRMI.errors` (command or instruction name -> ErrorID, once) and the pendant
with :attr:`FakeRMI.tp_enabled`; the lab's faults ``drop``, ``late``, ``garbage`` and
``disconnect`` act on the session's answers.
"""

from __future__ import annotations

import socket
import threading
import time
from typing import Any

import numpy as np

from drivers import rmi
from drivers.errors import ProtocolError
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World

ERROR_TEXT = {
    rmi.rmit(n): f"RMIT-{n:03d} {text}" for n, text in rmi.RMIT.items()
}


class _SessionPort(TcpFake):
    """The session listener; every packet is handled by the owning :class:`FakeRMI`."""

    driver = "fanuc-rmi"
    device = "fanuc-rmi"

    def __init__(self, owner: FakeRMI) -> None:
        super().__init__(owner.world)
        self.owner = owner

    def serve(self, conn: socket.socket) -> None:
        self.owner.serve_session(self, conn)


class FakeRMI(TcpFake):
    """RMI on loopback over the lab's world (see the module docstring)."""

    driver = "fanuc-rmi"
    device = "fanuc-rmi"

    def __init__(self, world: World, max_speed: float = 1.5, port: int = 0) -> None:
        """``port``: the connection port (0: a free one); the session port is always free."""
        super().__init__(world, port=port)
        self.session = _SessionPort(self)
        self.url = f"rmi://{self.host}:{self.port}"
        self.max_speed = max_speed
        self.tp_enabled = False
        self.errors: dict[str, int] = {}
        self.transcript: list[tuple[str, dict[str, Any]]] = []
        self._lock = threading.RLock()
        self._active = threading.Event()  # a session was announced
        self._session_open = threading.Event()
        self._handshake_t = 0.0
        self._initialized = False
        self._paused = False
        self._next_seq = 1
        self._override = 100
        self._uframe, self._utool = 0, 1
        self._last_error = 0
        self._pending: list[threading.Timer] = []
        self._motion: tuple[np.ndarray, np.ndarray, float, float] | None = None
        self._t0 = time.monotonic()
        self._last_reply = b""
        self.world_height = self._world_height()

    def start(self) -> None:
        self.session.start()
        super().start()

    def stop(self) -> None:
        for t in self._pending:
            t.cancel()
        self.session.stop()
        super().stop()

    # --- handshake port ---------------------------------------------------
    def serve(self, conn: socket.socket) -> None:
        while True:
            line = self.recv_line(conn, rmi.MAX_PACKET)
            if line is None:
                return
            try:
                packet = rmi.decode(line)
            except ProtocolError:
                return
            if packet.get("Communication") != "FRC_Connect":
                conn.sendall(rmi.encode({**self._name_of(packet), "ErrorID": rmi.rmit(13)}))
                continue
            deadline = time.monotonic() + 0.25  # a client that just closed its session
            while self._busy() and time.monotonic() < deadline:
                time.sleep(0.01)
            if self._busy():
                conn.sendall(rmi.encode({"Communication": "FRC_Connect",
                                         "ErrorID": rmi.rmit(26)}))
                continue
            self._active.set()
            self._handshake_t = time.monotonic()
            conn.sendall(rmi.encode({"Communication": "FRC_Connect", "ErrorID": 0,
                                     "PortNumber": self.session.port, "MajorVersion": 1,
                                     "MinorVersion": 0}))

    def _busy(self) -> bool:
        """A session is open, or was announced less than 2 s ago and not yet opened."""
        return self._session_open.is_set() or (
            self._active.is_set() and time.monotonic() - self._handshake_t < 2.0)

    @staticmethod
    def _name_of(packet: dict[str, Any]) -> dict[str, Any]:
        try:
            family, name = rmi.kind(packet)
        except ProtocolError:
            return {"Command": "Unknown"}
        return {family: name}

    # --- session port -----------------------------------------------------
    def serve_session(self, port: _SessionPort, conn: socket.socket) -> None:
        send_lock = threading.Lock()
        self._session_open.set()

        def send(packet: dict[str, Any]) -> None:
            if port.fault("drop"):
                return
            data = rmi.encode(packet)
            with send_lock:
                if port.fault("late") and self._last_reply:
                    conn.sendall(self._last_reply)
                if port.fault("garbage"):
                    data = np.random.default_rng().bytes(len(data) - 2) + b"\r\n"
                self._last_reply = data
                self.transcript.append(("answer", packet))
                conn.sendall(data)

        try:
            while True:
                line = port.recv_line(conn, rmi.MAX_PACKET)
                if line is None or port.fault("disconnect"):
                    return
                try:
                    packet = rmi.decode(line)
                    family, name = rmi.kind(packet)
                except ProtocolError:
                    return
                self.transcript.append(("request", packet))
                if family == "Communication":
                    if name == "FRC_Disconnect":
                        send({"Communication": "FRC_Disconnect", "ErrorID": 0})
                        return
                    send({"Communication": name, "ErrorID": rmi.rmit(13)})
                elif family == "Command":
                    send(self._command(name, packet))
                else:
                    self._instruction(name, packet, send)
        finally:
            with self._lock:  # the controller ends RMI when its client goes away
                self._initialized = False
                for t in self._pending:
                    t.cancel()
                self._pending.clear()
            self._session_open.clear()
            self._active.clear()

    def _error(self, reply: dict[str, Any], error_id: int) -> dict[str, Any]:
        self._last_error = error_id
        reply["ErrorID"] = error_id
        return reply

    def _command(self, name: str, packet: dict[str, Any]) -> dict[str, Any]:
        reply: dict[str, Any] = {"Command": name, "ErrorID": 0}
        with self._lock:
            if name in self.errors:
                return self._error(reply, self.errors.pop(name))
            if name == "FRC_Initialize":
                if self.tp_enabled:
                    return self._error(reply, rmi.rmit(8))
                if self._initialized:
                    return self._error(reply, rmi.rmit(15))
                self._initialized, self._paused, self._next_seq = True, False, 1
                reply["GroupMask"] = int(packet.get("GroupMask", 1))
            elif name == "FRC_Abort":
                self._abort()
            elif name in ("FRC_Pause", "FRC_Continue"):
                if not self._initialized:
                    return self._error(reply, rmi.rmit(9))
                self._paused = name == "FRC_Pause"
            elif name == "FRC_Reset":
                self._last_error = 0
            elif name == "FRC_GetStatus":
                reply.update(ServoReady=1, TPMode=int(self.tp_enabled),
                             RMIMotionStatus=int(self._initialized),
                             ProgramStatus=int(self._initialized) * (2 if self._paused else 1),
                             SingleStepMode=0, NumberUTool=self._utool,
                             NextSequenceID=self._next_seq, NumberUFrame=self._uframe,
                             Override=self._override)
            elif name == "FRC_ReadError":
                reply["Count"] = 1
                reply["ErrorData"] = ERROR_TEXT.get(self._last_error, "") \
                    if self._last_error else ""
            elif name == "FRC_ReadJointAngles":
                reply.update(TimeTag=self._time_tag(),
                             JointAngle=rmi.joint_object(self.world.joint_angles()),
                             Group=int(packet.get("Group", 1)))
            elif name == "FRC_ReadCartesianPosition":
                reply.update(TimeTag=self._time_tag(), **self._cartesian(),
                             Group=int(packet.get("Group", 1)))
            elif name == "FRC_SetOverRide":
                value = packet.get("Value")
                if not isinstance(value, int) or not 1 <= value <= 100:
                    return self._error(reply, rmi.rmit(5))
                self._override = value
            elif name == "FRC_GetUFrameUTool":
                reply.update(UFrameNumber=self._uframe, UToolNumber=self._utool,
                             Group=int(packet.get("Group", 1)))
            elif name == "FRC_SetUFrameUTool":
                uf, ut = packet.get("UFrameNumber"), packet.get("UToolNumber")
                if not isinstance(ut, int) or not 1 <= ut <= 10:
                    return self._error(reply, rmi.rmit(2))
                if not isinstance(uf, int) or not 0 <= uf <= 9:
                    return self._error(reply, rmi.rmit(3))
                self._uframe, self._utool = uf, ut
            else:
                return self._error(reply, rmi.rmit(13))
        return reply

    def _instruction(self, name: str, packet: dict[str, Any], send) -> None:
        seq = packet.get("SequenceID")
        reply: dict[str, Any] = {"Instruction": name, "ErrorID": 0, "SequenceID": seq}
        with self._lock:
            if name in self.errors:
                return send(self._error(reply, self.errors.pop(name)))
            if self.tp_enabled:
                return send(self._error(reply, rmi.rmit(8)))
            if not self._initialized:
                return send(self._error(reply, rmi.rmit(9)))
            if seq != self._next_seq:
                return send(self._error(reply, rmi.rmit(29)))
            delay = 0.0
            if name == "FRC_JointMotionJRep":
                code, delay = self._joint_motion(packet)
                if code:
                    return send(self._error(reply, code))
            elif name == "FRC_WaitTime":
                wait = packet.get("Time")
                if not isinstance(wait, (int, float)) or wait < 0:
                    return send(self._error(reply, rmi.rmit(21)))
                delay = float(wait) / self.world.settings.time_scale
            elif name in ("FRC_SetUFrame", "FRC_SetUTool"):
                pass
            else:
                return send(self._error(reply, rmi.rmit(20)))
            self._next_seq += 1
            timer = threading.Timer(delay, self._finish, args=(send, reply))
            timer.daemon = True
            self._pending.append(timer)
            timer.start()

    def _finish(self, send, reply: dict[str, Any]) -> None:
        with self._lock:
            self._pending = [t for t in self._pending if t.is_alive()
                             and t is not threading.current_thread()]
            self._motion = None
        try:
            send(reply)
        except OSError:
            pass

    def _joint_motion(self, packet: dict[str, Any]) -> tuple[int, float]:
        """Start the motion; (ErrorID, wall-clock duration)."""
        try:
            q = rmi.joint_angles(packet, self.world.robot.n)
        except ProtocolError:
            return rmi.rmit(36), 0.0
        if packet.get("SpeedType") != "Percent":
            return rmi.rmit(30), 0.0
        speed = packet.get("Speed")
        if not isinstance(speed, (int, float)) or not 0 < speed <= 100:
            return rmi.rmit(31), 0.0
        term = packet.get("TermType")
        if term not in ("FINE", "CNT"):
            return rmi.rmit(32), 0.0
        if term == "CNT" and not (isinstance(packet.get("TermValue"), int)
                                  and 0 <= packet["TermValue"] <= 100):
            return rmi.rmit(33), 0.0
        start = self.world.joint_angles()
        try:
            duration = self.world.move(q, self.max_speed * speed / 100 * self._override / 100)
        except ValueError:
            return rmi.rmit(36), 0.0
        self._motion = (start, q, time.monotonic(), duration)
        return 0, duration

    def _abort(self) -> None:
        """End RMI: cancel queued answers, stop the robot where it is."""
        for t in self._pending:
            t.cancel()
        self._pending.clear()
        if self._motion is not None:
            start, target, t0, duration = self._motion
            frac = min(1.0, (time.monotonic() - t0) / duration) if duration > 0 else 1.0
            self.world.move(start + frac * (target - start), 1e6)
            self._motion = None
        self._initialized = False

    def _world_height(self) -> float:
        """Height (m) of FANUC's world frame above the model's base: J2's axis at zero."""
        from analysis.model.kinematics import chain_state

        robot = self.world.robot
        if robot.n < 2:
            return 0.0
        return float(chain_state(robot, np.zeros(robot.n)).origins[1][2])

    def _time_tag(self) -> int:
        return int((time.monotonic() - self._t0) * 1000) & 0x7FFFFFFF

    def _cartesian(self) -> dict[str, Any]:
        from scipy.spatial.transform import Rotation

        T = self.world.nominal_tool_pose().copy()
        T[2, 3] -= self.world_height
        w, p, r = Rotation.from_matrix(T[:3, :3]).as_euler("xyz", degrees=True)
        x, y, z = T[:3, 3] * 1e3
        q = np.degrees(self.world.joint_angles())
        pos = {"X": x, "Y": y, "Z": z, "W": w, "P": p, "R": r, "Ext1": 0.0, "Ext2": 0.0,
               "Ext3": 0.0}
        config = {"UToolNumber": self._utool, "UFrameNumber": self._uframe,
                  "Front": int(abs(q[0]) < 90), "Up": 1, "Left": 0,
                  "Flip": int(q[4] < 0), "Turn4": 0, "Turn5": 0, "Turn6": 0}
        return {"Configuration": config,
                "Position": {k: round(float(v), 4) for k, v in pos.items()}}
