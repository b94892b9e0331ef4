"""Fake ATI Net CAN: a node on a socketcand bus on 127.0.0.1 (or python-can's ``virtual`` bus).

Across processes (``campaign lab --fake``) the sensor sits on a CAN bus served
by :class:`drivers.sim.socketcand.CanHub` on loopback: any socketcand client
(python-can's ``socketcand`` interface, the driver's default in the lab's
address) reaches it, and nothing leaves the host. Inside one process the
``virtual`` interface of python-can is used as well.

The node answers requests only: frames on its identifiers with the request's
length (no data for opcodes 0x0, 0x7, 0x8; one byte for 0x2). Its own answers
carry data, so a node that heard its own frames still would not answer them.
"""

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

#: bus name the socketcand server serves
BUS_NAME = "can0"
#: python-can interfaces the fake can sit on
INTERFACES = ("socketcand", "virtual")


class FakeNetCAN(FakeServer):
    """Answers Net CAN requests from the world's sensor wrench through a calibration matrix."""

    driver = "ati-netcan"
    device = "ati-netcan"

    def __init__(self, world: World, interface: str = "socketcand", base_id: int = 0x7F,
                 channel: str | None = None) -> None:
        super().__init__(world)
        if interface not in INTERFACES:
            raise ValueError(f"Net CAN fake interface {interface!r}: use one of "
                             f"{', '.join(INTERFACES)} (both stay on this host)")
        self.interface = interface
        self.base_id = base_id
        self.cpf, self.cpt = 1000, 10000  # counts per N, per N m
        rng = np.random.default_rng(world.settings.seed + 7)
        self.matrix = 50.0 * (np.eye(6) + 0.05 * rng.standard_normal((6, 6)))
        self._last_sg: np.ndarray | None = None
        self._dead = False
        self.bus = self.hub = None
        if interface == "socketcand":
            from drivers.sim.socketcand import CanHub

            self.channel = channel or BUS_NAME
            self.hub = CanHub(self.channel, self._answer)
            self.url = (f"can://{self.channel}?interface=socketcand&host={self.hub.host}"
                        f"&port={self.hub.port}&base_id=0x{base_id:x}")
        else:
            import can

            self.channel = channel or f"netcan-{uuid.uuid4().hex[:8]}"
            self.bus = can.Bus(channel=self.channel, interface="virtual")
            self.url = f"can://{self.channel}?interface=virtual&base_id=0x{base_id:x}"

    def _close(self) -> None:
        if self.hub is not None:
            self.hub.close()

    def _sg(self) -> np.ndarray:
        if self._last_sg is not None and self.world.faults.active(self.device, "frozen"):
            return self._last_sg
        w = self.world.sensor_wrench(self.device)
        counts = w * np.array([self.cpf] * 3 + [self.cpt] * 3)
        sg = np.clip(np.round(np.linalg.solve(self.matrix, counts)), -32767, 32767)
        self._last_sg = sg
        return sg

    def _answer(self, arbitration_id: int, extended: bool, data: bytes) -> list[tuple[int, bytes]]:
        """Frames (id, data) the sensor sends in answer to one frame it heard."""
        if self._dead or extended or arbitration_id >> 4 != self.base_id:
            return []
        op = arbitration_id & 0xF
        is_request = (len(data) == 1 and data[0] < 6) if op == OP_MATRIX else \
            (not data and op in (OP_SG0, OP_COUNTS, OP_UNITS))
        if not is_request:
            return []  # an answer (ours, or another sensor's) or an unknown opcode
        if self.fault("disconnect"):
            self._dead = True
            return []
        if self.fault("drop"):
            return []
        ident = lambda o: can_id(self.base_id, o)  # noqa: E731 - local shorthand
        if op == OP_SG0:
            a, b = encode_sg_frames(0, self._sg())
            if self.fault("garbage"):
                a = os.urandom(int(self.world.rng.integers(1, 8)))  # never 0 (a request) or 8
            return [(ident(OP_SG0), a), (ident(OP_SG1), b)]
        if op == OP_MATRIX:
            row = self.matrix[data[0]]
            return [(ident(OP_MATRIX + k), struct.pack(">2f", row[2 * k], row[2 * k + 1]))
                    for k in range(3)]
        if op == OP_COUNTS:
            return [(ident(OP_COUNTS), struct.pack(">2i", self.cpf, self.cpt))]
        return [(ident(OP_UNITS), bytes([2, 3]))]

    def _run(self) -> None:
        if self.hub is not None:
            self.hub.serve()
            return
        import can

        while not self.stopping.is_set():
            msg = self.bus.recv(0.05)
            if msg is None or msg.is_remote_frame:
                continue
            for ident, payload in self._answer(msg.arbitration_id, msg.is_extended_id,
                                               bytes(msg.data)):
                self.bus.send(can.Message(arbitration_id=ident, data=payload,
                                          is_extended_id=False))
        self.bus.shutdown()
