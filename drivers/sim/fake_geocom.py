"""Fake GeoCOM-style instrument on loopback TCP: TMC_DoMeasure and TMC_GetCoordinate."""

from __future__ import annotations

import os
import socket
import threading

from drivers.errors import ProtocolError
from drivers.geocom import RPC_DO_MEASURE, RPC_GET_COORDINATE, decode_request, encode_reply
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World

RC_ANGLE_ONLY = 1285  # TMC_ANGLE_OK: no distance, as when the beam is lost
RC_UNKNOWN_RPC = 1  # GRC_IVRESULT is close enough for an RPC the fake does not know


class FakeGeoCom(TcpFake):
    """Serves the aimed reflector's coordinates (m) of the world."""

    driver = "geocom"
    device = "geocom"

    def __init__(self, world: World) -> None:
        super().__init__(world)
        self.url = f"socket://{self.host}:{self.port}"

    def _late(self, conn: socket.socket, reply: bytes, delay: float = 1.5) -> None:
        """Send ``reply`` after ``delay`` s, from another thread (a slow instrument)."""
        timer = threading.Timer(delay, lambda: self._send_quietly(conn, reply))
        timer.daemon = True
        timer.start()

    @staticmethod
    def _send_quietly(conn: socket.socket, data: bytes) -> None:
        try:
            conn.sendall(data)
        except OSError:
            pass

    def serve(self, conn: socket.socket) -> None:
        while True:
            line = self.recv_line(conn)
            if line is None:
                return
            try:
                rpc, _params, trid = decode_request(line)
            except ProtocolError:
                conn.sendall(b"%R1P,1,0:\r\n")  # communication error reply
                continue
            if self.fault("disconnect"):
                return
            if self.fault("drop"):
                continue
            if self.fault("garbage"):
                conn.sendall(os.urandom(int(self.world.rng.integers(1, 60))) + b"\r\n")
                continue
            if rpc == RPC_DO_MEASURE:
                conn.sendall(encode_reply(0, trid=trid))
            elif rpc == RPC_GET_COORDINATE:
                if self.fault("beam_lost"):
                    conn.sendall(encode_reply(RC_ANGLE_ONLY, 0, 0, 0, 0, 0, 0, 0, 0, trid=trid))
                    continue
                e, n, h = self.world.tracker_point()
                reply = encode_reply(0, f"{e:.7f}", f"{n:.7f}", f"{h:.7f}", 0,
                                     f"{e:.7f}", f"{n:.7f}", f"{h:.7f}", 0, trid=trid)
                if self.fault("late"):
                    self._late(conn, reply)
                    continue
                conn.sendall(reply)
            else:
                conn.sendall(encode_reply(RC_UNKNOWN_RPC, trid=trid))
