"""Fake emScon laser tracker on loopback TCP (single points and 6-DoF stationary probe results).

Packet layouts are those of :mod:`drivers.emscon` (``SingleMeasResultT``,
``ProbeStationaryResultT``, ``ProbePosResultT`` of Leica's ``ES_C_API_Def.h``).
"""

from __future__ import annotations

import os
import socket
import struct

import numpy as np

from drivers.emscon import (
    C_START_MEASUREMENT,
    CMD_BODY,
    DT_COMMAND,
    DT_ERROR,
    DT_PROBE_POS,
    DT_PROBE_STATIONARY,
    DT_REFLECTOR_POS,
    DT_SINGLE,
    HEADERS,
    REPLY_BODY,
    encode_packet,
    encode_probe,
    encode_probe_position,
    encode_single,
)
from drivers.frames import matrix_to_quat
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World

NOT_READY = 10014  # ES_RS_SystemNotReadyForMeasurement
REFLECTOR_POS_BODY = struct.Struct("<i3d")  # ReflectorPosResultT after the header


class FakeEmscon(TcpFake):
    """Answers StartMeasurement with the world's aimed reflector (or the 6-DoF probe pose).

    ``mode`` is ``"point"`` or ``"6dof"``; lengths are sent in millimetres.
    ``position_stream`` sends an unsolicited reflector/probe position packet
    (as with ``bSendReflectorPositionData``) between acknowledgement and result.
    """

    driver = "emscon"
    device = "emscon"

    def __init__(self, world: World, mode: str = "point", header: str = "int32",
                 position_stream: bool = False, port: int = 0) -> None:
        super().__init__(world, port=port)
        self.mode, self.header, self.position_stream = mode, header, position_stream
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
        s = self.world.settings
        if self.mode == "6dof":
            T = self.world.tracker_pose(self.device)
            xyz, q = T[:3, 3] * 1000, matrix_to_quat(T[:3, :3])
            result = encode_packet(DT_PROBE_STATIONARY, encode_probe(
                0, xyz, q, std=np.full(3, s.tracker_noise * 1000),
                std_angles=np.full(3, s.tracker_angle_noise)), self.header)
            stream = encode_packet(DT_PROBE_POS, encode_probe_position(xyz, q), self.header)
        else:
            p = self.world.tracker_point(source=self.device) * 1000
            std = np.full(3, s.tracker_noise * 1000)
            result = encode_packet(DT_SINGLE, encode_single(0, p, std), self.header)
            stream = encode_packet(DT_REFLECTOR_POS, REFLECTOR_POS_BODY.pack(0, *p), self.header)
        return stream + result if self.position_stream else result
