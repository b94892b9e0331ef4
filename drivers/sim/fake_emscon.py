"""Fake emScon-style laser tracker on loopback TCP (single points and 6-DoF probe)."""

from __future__ import annotations

import os
import socket

import numpy as np

from drivers.emscon import (
    C_START_MEASUREMENT,
    CMD_BODY,
    DT_COMMAND,
    DT_ERROR,
    DT_PROBE,
    DT_SINGLE,
    HEADERS,
    REPLY_BODY,
    encode_packet,
    encode_probe,
    encode_single,
)
from drivers.frames import matrix_to_quat
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World

NOT_READY = 10014  # ES_RS_SystemNotReadyForMeasurement


class FakeEmscon(TcpFake):
    """Answers StartMeasurement with the world's aimed reflector (or the 6-DoF probe pose).

    ``mode`` is ``"point"`` or ``"6dof"``; lengths are sent in millimetres.
    """

    driver = "emscon"
    device = "emscon"

    def __init__(self, world: World, mode: str = "point", header: str = "int32") -> None:
        super().__init__(world)
        self.mode, self.header = mode, header
        self.url = f"socket://{self.host}:{self.port}?header={header}&length_unit=mm"

    def serve(self, conn: socket.socket) -> None:
        h = HEADERS[self.header]
        while True:
            head = self.recv_exact(conn, h.size)
            if head is None:
                return
            size, ptype = h.unpack(head)
            if size < h.size or size > 65536:
                return  # a real server drops a client that sends nonsense
            body = self.recv_exact(conn, size - h.size)
            if body is None:
                return
            if ptype != DT_COMMAND or len(body) < CMD_BODY.size:
                continue
            (command,) = CMD_BODY.unpack(body[: CMD_BODY.size])
            if self.fault("disconnect"):
                return
            if self.fault("drop"):
                continue
            if command != C_START_MEASUREMENT:
                conn.sendall(encode_packet(DT_COMMAND, REPLY_BODY.pack(command, 2), self.header))
                continue
            if self.world.faults.active(self.device, "beam_lost"):
                self.world.faults.take(self.device, "beam_lost")
                conn.sendall(encode_packet(DT_ERROR, REPLY_BODY.pack(command, NOT_READY),
                                           self.header))
                continue
            conn.sendall(encode_packet(DT_COMMAND, REPLY_BODY.pack(command, 0), self.header))
            if self.fault("garbage"):
                conn.sendall(os.urandom(int(self.world.rng.integers(1, 200))))
                continue
            conn.sendall(self._result())

    def _result(self) -> bytes:
        if self.mode == "6dof":
            T = self.world.tracker_pose()
            return encode_packet(DT_PROBE, encode_probe(0, T[:3, 3] * 1000,
                                                        matrix_to_quat(T[:3, :3])), self.header)
        p = self.world.tracker_point()
        std = np.full(3, self.world.settings.tracker_noise * 1000)
        return encode_packet(DT_SINGLE, encode_single(0, p * 1000, std), self.header)
