"""Fake KUKAVARPROXY: KRL system variables of a simulated KR C4 plus the shipped KRL loop.

Answers what the real proxy answers (message format in :mod:`drivers.kvp`):

* reads of the common system variables (:mod:`drivers.sim.krl_vars`): ``$AXIS_ACT``,
  ``$AXIS_ACT_MEAS``, ``$POS_ACT``, ``$POS_ACT_MES``, ``$TOOL``, ``$BASE``, ``$OV_PRO``,
  ``$MODE_OP``, ``$PRO_STATE1``, ``$VEL_ACT``, ``$ROB_STOPPED``, ``$ON_PATH``,
  ``$PERI_RDY``, ``$STOPMESS``, ``$ACT_TOOL``, ``$ACT_BASE``, ``$MODEL_NAME[]``,
  ``$ROBNAME[]``, ``$KR_SERIALNO``, ``$IN[n]``, ``$OUT[n]``, ``$VEL_AXIS[n]``,
  ``$ACC_AXIS[n]``, and ``PING`` (-> ``PONG``, answered by the proxy itself);
* the globals of ``drivers/krl/stiff_loop.dat`` (``STIFF_*``), running the program's
  PTP motion when ``STIFF_GO`` becomes TRUE;
* writes to ``$OV_PRO`` (0..100), ``$OUT[n]``, ``$VEL_AXIS[n]``, ``$ACC_AXIS[n]``,
  ``$TOOL``/``$BASE`` are accepted; a write to a read-only or unknown variable, or a
  value of the wrong type, gets the failure flag with the value echoed;
* a read of an unknown name gets an empty value with the success flag, as the real
  proxy gives (its ShowVar swallows the cross-comm error); a function other than read
  or write gets a header with content length 0.
"""

from __future__ import annotations

import re
import socket
import struct
import threading

import numpy as np

from analysis.model.kinematics import chain_state
from drivers import kvp
from drivers.errors import ProtocolError
from drivers.sim import krl_vars as krl
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World

_BOOL = re.compile(r"^(TRUE|FALSE)$", re.IGNORECASE)
_INT = re.compile(r"^[-+]?\d+$")


class FakeKukaVarProxy(TcpFake):
    """KUKAVARPROXY on loopback over the lab's world (see the module docstring)."""

    driver = "kuka-kvp"
    device = "kuka-kvp"

    def __init__(self, world: World, max_speed: float = 1.5, port: int = 0) -> None:
        super().__init__(world, port=port)
        self.url = f"socket://{self.host}:{self.port}"
        self.max_speed = max_speed
        q0 = kvp.format_axis(world.joint_angles(self.device))
        self.vars = {"STIFF_GO": "FALSE", "STIFF_STOP": "FALSE", "STIFF_VEL": "10",
                     "STIFF_ACC": "10", "STIFF_TARGET": q0,
                     "$OV_PRO": "100", "$MODE_OP": "#AUT", "$PRO_STATE1": "#P_ACTIVE",
                     "$ACT_TOOL": "1", "$ACT_BASE": "0", "$KR_SERIALNO": "240002",
                     "$TOOL": krl.frame(self._tool_frame()), "$BASE": krl.frame(np.eye(4))}
        self.io = {"$IN": {}, "$OUT": {}, "$VEL_AXIS": {}, "$ACC_AXIS": {}}
        self.phi_deg = self._elbow_phi()
        self._lock = threading.Lock()

    # --- geometry of the status bits -------------------------------------
    def _tool_frame(self) -> np.ndarray:
        T = np.eye(4)
        T[:3, 3] = self.world.settings.tool_xyz
        from scipy.spatial.transform import Rotation

        T[:3, :3] = Rotation.from_euler("xyz", self.world.settings.tool_rpy).as_matrix()
        return T

    def _elbow_phi(self) -> float:
        """A3 (deg) at which the wrist centre lies on the line A2-A3 (KUKA's phi)."""
        robot = self.world.robot
        if robot.n != 6:
            return 0.0
        q_ctrl = np.radians([0.0, -90.0, 0.0, 0.0, 0.0, 0.0])
        s = chain_state(robot, robot.from_controller(q_ctrl))
        u, v = s.origins[2] - s.origins[1], s.origins[4] - s.origins[2]
        axis = s.axes[2] * robot.controller_sign[2]  # positive A3 turns about this
        delta = np.arctan2(np.dot(axis, np.cross(u, v)), np.dot(u, v))
        return float(np.degrees(-delta))

    def _pos_act(self) -> str:
        robot = self.world.robot
        q_ctrl = self.world.joint_angles(self.device)
        q_deg = np.degrees(q_ctrl)
        q = robot.from_controller(q_ctrl)
        s = chain_state(robot, q)
        wrist = s.origins[min(4, robot.n - 1)]
        x1 = np.array([np.cos(q[0]), np.sin(q[0])])  # model x1 axis in the base plane
        status = krl.status_bits(float(np.dot(wrist[:2], x1)), q_deg[2], self.phi_deg,
                                 q_deg[4] if robot.n > 4 else 1.0)
        return krl.e6pos(self.world.nominal_tool_pose(), status, krl.turn_bits(q_deg))

    # --- variables --------------------------------------------------------
    def _read(self, name: str) -> str:
        key = name.strip().upper()
        if key == "PING":
            return "PONG"
        if key in ("$AXIS_ACT", "$AXIS_ACT_MEAS"):
            return krl.e6axis(np.degrees(self.world.joint_angles(self.device)))
        if key in ("$POS_ACT", "$POS_ACT_MES"):
            return self._pos_act()
        moving = self.world.moving()
        if key == "$VEL_ACT":
            return "0.0" if not moving else krl.real(0.1)
        if key == "$ROB_STOPPED":
            return "FALSE" if moving else "TRUE"
        if key in ("$ON_PATH", "$PERI_RDY"):
            return "TRUE"
        if key == "$STOPMESS":
            return "FALSE"
        if key in ("$MODEL_NAME[]", "$ROBNAME[]"):
            return f'"{self.world.robot.name}"'
        slot = krl.indexed(key)
        if slot is not None:
            base, idx = slot
            default = "FALSE" if base in ("$IN", "$OUT") else "100"
            with self._lock:
                return self.io[base].get(idx, default)
        with self._lock:
            return self.vars.get(key, "")

    def _write(self, name: str, value: str) -> bool:
        key, value = name.strip().upper(), value.strip()
        slot = krl.indexed(key)
        if slot is not None:
            base, idx = slot
            if base == "$IN":
                return False
            if base == "$OUT":
                ok = bool(_BOOL.match(value))
                value = value.upper()
            else:
                ok = bool(_INT.match(value)) and 1 <= int(value) <= 100
            if ok:
                with self._lock:
                    self.io[base][idx] = value
            return ok
        if key in krl.READ_ONLY or key not in self.vars:
            return False
        if key == "$OV_PRO" and not (_INT.match(value) and 0 <= int(value) <= 100):
            return False
        if key in ("$TOOL", "$BASE") and not value.upper().startswith("{"):
            return False
        with self._lock:
            self.vars[key] = value
        if key == "STIFF_GO" and value.upper() == "TRUE":
            self._start_motion()
        return True

    def _start_motion(self) -> None:
        try:
            q = kvp.parse_axis(self.vars["STIFF_TARGET"])
            speed = self.max_speed * int(self.vars["STIFF_VEL"]) / 100
            duration = self.world.move(q, speed)
        except (ProtocolError, ValueError):
            with self._lock:  # the KRL program would stop with an error message
                self.vars["STIFF_GO"] = "FALSE"
            return

        def done() -> None:
            with self._lock:
                self.vars["STIFF_GO"] = "FALSE"

        timer = threading.Timer(duration, done)
        timer.daemon = True
        timer.start()

    # --- wire -------------------------------------------------------------
    def serve(self, conn: socket.socket) -> None:
        while True:
            head = self.recv_exact(conn, 4)
            if head is None:
                return
            msg_id, length = struct.unpack(">HH", head)
            body = self.recv_exact(conn, length)
            if body is None:
                return
            if self.fault("disconnect"):
                return
            if self.fault("drop"):
                continue
            if not body or body[0] not in (kvp.READ, kvp.WRITE):
                conn.sendall(struct.pack(">HH", msg_id, 0))  # the proxy's empty answer
                continue
            try:
                msg_id, func, name, value = kvp.decode_request(head + body)
            except ProtocolError:
                return
            if func == kvp.READ:
                reply = kvp.encode_reply(msg_id, func, self._read(name))
            else:
                ok = self._write(name, value or "")
                reply = kvp.encode_reply(msg_id, func, value or "", ok=ok)
            if self.fault("garbage"):
                reply = np.random.default_rng().bytes(len(reply))
            conn.sendall(reply)
