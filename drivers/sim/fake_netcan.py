"""Fake ATI Net CAN on a python-can bus (``virtual`` in one process, ``udp_multicast`` across)."""

from __future__ import annotations

import os
import struct
import uuid

import numpy as np

from drivers.ati_netcan import (
    OP_COUNTS,
    OP_MATRIX,
    OP_SG0,
    OP_SG1,
    OP_UNITS,
    can_id,
    encode_sg_frames,
)
from drivers.sim.base import FakeServer
from drivers.sim.world import World

UDP_GROUP = "239.74.163.2"


class FakeNetCAN(FakeServer):
    """Answers Net CAN requests from the world's sensor wrench through a calibration matrix."""

    driver = "ati-netcan"
    device = "ati-netcan"

    def __init__(self, world: World, interface: str = "virtual", base_id: int = 0x7F,
                 channel: str | None = None) -> None:
        import can

        super().__init__(world)
        self.base_id = base_id
        self.cpf, self.cpt = 1000, 10000  # counts per N, per N m
        rng = np.random.default_rng(world.settings.seed + 7)
        self.matrix = 50.0 * (np.eye(6) + 0.05 * rng.standard_normal((6, 6)))
        self.channel = channel or (UDP_GROUP if interface == "udp_multicast"
                                   else f"netcan-{uuid.uuid4().hex[:8]}")
        self.bus = can.Bus(channel=self.channel, interface=interface)
        self.url = f"can://{self.channel}?interface={interface}&base_id=0x{base_id:x}"
        self._last_sg: np.ndarray | None = None

    def _close(self) -> None:
        pass

    def _send(self, opcode: int, data: bytes) -> None:
        import can

        self.bus.send(can.Message(arbitration_id=can_id(self.base_id, opcode), data=data,
                                  is_extended_id=False))

    def _sg(self) -> np.ndarray:
        if self._last_sg is not None and self.world.faults.active(self.device, "frozen"):
            return self._last_sg
        w = self.world.sensor_wrench()
        counts = w * np.array([self.cpf] * 3 + [self.cpt] * 3)
        sg = np.clip(np.round(np.linalg.solve(self.matrix, counts)), -32767, 32767)
        self._last_sg = sg
        return sg

    def _run(self) -> None:
        dead = False
        while not self.stopping.is_set():
            msg = self.bus.recv(0.05)
            if msg is None or dead:
                continue
            if self.fault("disconnect"):
                dead = True
                continue
            if msg.arbitration_id >> 4 != self.base_id:
                continue
            op = msg.arbitration_id & 0xF
            if self.fault("drop"):
                continue
            if op == OP_SG0:
                a, b = encode_sg_frames(0, self._sg())
                if self.fault("garbage"):
                    a = os.urandom(int(self.world.rng.integers(0, 8)))
                self._send(OP_SG0, a)
                self._send(OP_SG1, b)
            elif op == OP_MATRIX and len(msg.data) == 1 and msg.data[0] < 6:
                row = self.matrix[msg.data[0]]
                for k in range(3):
                    self._send(OP_MATRIX + k, struct.pack(">2f", row[2 * k], row[2 * k + 1]))
            elif op == OP_COUNTS:
                self._send(OP_COUNTS, struct.pack(">2i", self.cpf, self.cpt))
            elif op == OP_UNITS:
                self._send(OP_UNITS, bytes([2, 3]))
        self.bus.shutdown()
