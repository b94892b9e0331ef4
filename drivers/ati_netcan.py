"""ATI Net CAN (Net F/T with CAN bus / "Net CANbus OEM") force/torque sensor via python-can.

Protocol, from ATI's *Net CAN OEM Installation and Operation Manual*
(document 9610-05-1030), section "CAN bus protocol":

* Every frame has an 11-bit identifier ``(base_id << 4) | opcode``; ``base_id``
  is the sensor's 7-bit base identifier. Payloads are big-endian.
* Opcode 0x0 "read strain gauge data" (request without data) is answered by two
  frames: opcode 0x0 with ``uint16 status, int16 SG0, SG2, SG4`` and opcode 0x1
  with ``int16 SG1, SG3, SG5``.
* Opcode 0x2 "read matrix" with one data byte (row 0..5 = Fx..Tz) is answered by
  opcodes 0x2, 0x3, 0x4, each holding two ``float32`` (SG0 SG1, SG2 SG3, SG4 SG5).
* Opcode 0x7 "read counts per unit": ``int32`` counts per force, counts per torque.
* Opcode 0x8 "read unit codes": ``uint8`` force unit, ``uint8`` torque unit
  (force 1 lbf, 2 N, 3 klbf, 4 kN, 5 kgf, 6 gf; torque 1 lbf-in, 2 lbf-ft,
  3 N-m, 4 N-mm, 5 kgf-cm, 6 kN-m).

The host applies the calibration: ``FT = (C @ SG) / counts_per_unit``, then
converts to SI. A non-zero status word raises :class:`DeviceFault`.
"""

from __future__ import annotations

import struct
import time
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.roles import ForceTorqueSensor
from drivers.units import force_factor, torque_factor

OP_SG0 = 0x0
OP_SG1 = 0x1
OP_MATRIX = 0x2
OP_COUNTS = 0x7
OP_UNITS = 0x8
FORCE_UNITS = {1: "lbf", 2: "N", 3: "klbf", 4: "kN", 5: "kgf", 6: "g"}
TORQUE_UNITS = {1: "lbf-in", 2: "lbf-ft", 3: "N-m", 4: "N-mm", 5: "kgf-cm", 6: "kN-m"}


def can_id(base_id: int, opcode: int) -> int:
    """11-bit identifier of ``opcode`` for a sensor with 7-bit ``base_id``."""
    if not 0 <= base_id <= 0x7F:
        raise ValueError(f"base id must be 7 bits, got 0x{base_id:x}")
    return (base_id << 4) | opcode


def decode_sg_frames(first: bytes, second: bytes) -> tuple[int, np.ndarray]:
    """Decode the two strain-gauge frames into ``(status, sg[6])``.

    Raises
    ------
    ProtocolError
        If the payload lengths are not 8 and 6 bytes.
    """
    if len(first) != 8 or len(second) != 6:
        raise ProtocolError(f"SG frames must be 8 and 6 bytes, got {len(first)} and {len(second)}")
    status, g0, g2, g4 = struct.unpack(">H3h", first)
    g1, g3, g5 = struct.unpack(">3h", second)
    return status, np.array([g0, g1, g2, g3, g4, g5], dtype=float)


def encode_sg_frames(status: int, sg: np.ndarray) -> tuple[bytes, bytes]:
    """Inverse of :func:`decode_sg_frames` (used by the fake)."""
    g = [int(v) for v in sg]
    return struct.pack(">H3h", status, g[0], g[2], g[4]), struct.pack(">3h", g[1], g[3], g[5])


class NetCANSensor(ForceTorqueSensor):
    """ATI Net CAN sensor, polled: one request, two answer frames per sample.

    Parameters
    ----------
    address : str
        ``can://CHANNEL?interface=socketcan&base_id=0x7f`` (any python-can
        interface; ``bitrate`` passed on when given), or through a socketcand
        server ``can://can0?interface=socketcand&host=HOST&port=PORT&base_id=0x7f``.

    Every answer frame carries data, so a frame without data on an answer
    identifier (a request: another node's, or ours echoed by a bus that loops
    frames back) is not taken for an answer.
    """

    rate_hz = 200.0
    retries = 2

    def __init__(self, address: str, *, timeout: float = 0.5, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address)
        if addr.scheme != "can":
            raise ConnectionFailed(f"{address!r}: expected can://channel?interface=...")
        self.channel = addr.path
        self.interface = addr.option("interface", "socketcan")
        self.base_id = addr.int_option("base_id", 0x7F)
        self.bitrate = addr.options.get("bitrate")
        self.host = addr.options.get("host")
        self.port = addr.int_option("port", 29536) if self.host else None
        self._bus = None
        self.matrix = np.eye(6)
        self.scale = np.ones(6)

    def _connect(self) -> None:
        import can

        kwargs: dict[str, Any] = {"channel": self.channel, "interface": self.interface}
        if self.bitrate:
            kwargs["bitrate"] = int(self.bitrate)
        if self.host:
            kwargs.update(host=self.host, port=self.port)
        elif self.interface == "socketcand":
            raise ConnectionFailed(f"{self.address}: socketcand needs host= and port= options")
        try:
            self._bus = can.Bus(**kwargs)
        except (can.CanError, OSError, ValueError, ImportError) as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err
        rows = []
        for axis in range(6):
            frames = self._request(OP_MATRIX, bytes([axis]), (OP_MATRIX, OP_MATRIX + 1,
                                                              OP_MATRIX + 2))
            row = []
            for op in (OP_MATRIX, OP_MATRIX + 1, OP_MATRIX + 2):
                if len(frames[op]) != 8:
                    raise ProtocolError("matrix frame must hold two float32")
                row.extend(struct.unpack(">2f", frames[op]))
            rows.append(row)
        self.matrix = np.array(rows)
        cpu = self._request(OP_COUNTS, b"", (OP_COUNTS,))[OP_COUNTS]
        units = self._request(OP_UNITS, b"", (OP_UNITS,))[OP_UNITS]
        if len(cpu) != 8 or len(units) < 2:
            raise ProtocolError("bad counts-per-unit or unit-code frame")
        cpf, cpt = struct.unpack(">2i", cpu)
        if cpf <= 0 or cpt <= 0:
            raise ProtocolError(f"counts per unit must be positive, got {cpf}, {cpt}")
        try:
            fu, tu = FORCE_UNITS[units[0]], TORQUE_UNITS[units[1]]
        except KeyError as err:
            raise ProtocolError(f"unknown unit codes {units[0]}, {units[1]}") from err
        self.units = (fu, tu)
        self.scale = np.array([force_factor(fu) / cpf] * 3 + [torque_factor(tu) / cpt] * 3)

    def _close(self) -> None:
        if self._bus is not None:
            self._bus.shutdown()
            self._bus = None

    def _request(self, opcode: int, data: bytes, answers: tuple[int, ...]) -> dict[int, bytes]:
        """Send one request and collect the answer frames, retrying a bounded number of times."""
        import can

        if self._bus is None:
            raise ConnectionFailed("not connected")
        wanted = {can_id(self.base_id, op): op for op in answers}
        for _attempt in range(self.retries + 1):
            try:
                self._bus.send(can.Message(arbitration_id=can_id(self.base_id, opcode),
                                           data=data, is_extended_id=False))
            except can.CanError as err:
                raise ConnectionFailed(f"{self.address}: {err}") from err
            got: dict[int, bytes] = {}
            deadline = time.monotonic() + self.timeout / (self.retries + 1)
            while len(got) < len(answers):
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                try:
                    msg = self._bus.recv(left)
                except can.CanError as err:
                    raise ConnectionFailed(f"{self.address}: {err}".splitlines()[0]) from err
                if msg is None:
                    break
                op = wanted.get(msg.arbitration_id)
                if op is not None and not msg.is_remote_frame and msg.data:
                    got[op] = bytes(msg.data)
            if len(got) == len(answers):
                return got
        raise DeviceTimeout(f"{self.address}: no complete answer to opcode 0x{opcode:x}")

    def _discard_buffered(self) -> None:
        while self._bus is not None and self._bus.recv(0) is not None:
            pass

    def _read_sample(self) -> np.ndarray:
        frames = self._request(OP_SG0, b"", (OP_SG0, OP_SG1))
        status, sg = decode_sg_frames(frames[OP_SG0], frames[OP_SG1])
        if status != 0:
            raise DeviceFault(f"Net CAN status word 0x{status:04x} reports a fault")
        if np.any(np.abs(sg) >= 32767):
            raise DeviceFault("Net CAN strain gauge saturated")
        return (self.matrix @ sg) * self.scale

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(base_id=self.base_id, interface=self.interface)
        return d
