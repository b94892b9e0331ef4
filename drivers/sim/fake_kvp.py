"""Fake KUKAVARPROXY plus the behaviour of the shipped KRL loop program."""

from __future__ import annotations

import socket
import struct
import threading

import numpy as np

from drivers import kvp
from drivers.errors import ProtocolError
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World


class FakeKukaVarProxy(TcpFake):
    """Serves ``$AXIS_ACT`` from the world and runs STIFF_TARGET motions like stiff_loop.src."""

    driver = "kuka-kvp"
    device = "kuka-kvp"

    def __init__(self, world: World, max_speed: float = 1.5) -> None:
        super().__init__(world)
        self.url = f"socket://{self.host}:{self.port}"
        self.max_speed = max_speed
        self.vars = {"STIFF_GO": "FALSE", "STIFF_STOP": "FALSE", "STIFF_VEL": "10",
                     "STIFF_ACC": "10", "STIFF_TARGET": kvp.format_axis(world.joint_angles())}
        self._lock = threading.Lock()

    def _read(self, name: str) -> str | None:
        key = name.upper()
        if key == "$AXIS_ACT":
            return kvp.format_axis(self.world.joint_angles())
        with self._lock:
            return self.vars.get(key)

    def _write(self, name: str, value: str) -> bool:
        key = name.upper()
        if key not in self.vars:
            return False
        with self._lock:
            self.vars[key] = value
        if key == "STIFF_GO" and value.strip().upper() == "TRUE":
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

    def serve(self, conn: socket.socket) -> None:
        while True:
            head = self.recv_exact(conn, 4)
            if head is None:
                return
            (length,) = struct.unpack(">H", head[2:])
            body = self.recv_exact(conn, length)
            if body is None:
                return
            try:
                msg_id, func, name, value = kvp.decode_request(head + body)
            except ProtocolError:
                return
            if self.fault("disconnect"):
                return
            if self.fault("drop"):
                continue
            if func == kvp.READ:
                text = self._read(name)
                reply = kvp.encode_reply(msg_id, func, text or "", ok=text is not None)
            else:
                ok = self._write(name, value or "")
                reply = kvp.encode_reply(msg_id, func, value or "", ok=ok)
            if self.fault("garbage"):
                reply = np.random.default_rng().bytes(len(reply))
            conn.sendall(reply)
