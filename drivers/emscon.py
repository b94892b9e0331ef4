"""Laser tracker over Leica emScon-style binary packets on TCP (port 700).

Packet layout from Leica's emScon TPI C header ``ES_C_API_Def.h`` (structures
``PacketHeaderT``, ``BasicCommandCT/RT``, ``ErrorResponseT``,
``SingleMeasResultT``, ``ProbePosResultT``), little-endian, 4-byte packing:

* header: ``lPacketSize`` (whole packet, bytes) and ``type`` (ES_DataType:
  0 command, 1 error, 2 single measurement result, 11 probe position result).
  **Header layout is an option** because public sources disagree: the C header
  declares ``long`` (4 bytes with the Windows compilers emScon targets) giving
  ``int32 size, int32 type`` (``header="int32"``, default), whereas the
  community CESAPI Python package packs ``int64 size, uint32 type``
  (``header="int64"``). Choose with ``?header=int64`` in the address.
* command: header + ``int32 command`` (ES_C_StartMeasurement = 49); its answer:
  header + ``int32 command, int32 status`` (ES_ResultStatus, 0 = all OK).
* error: header + ``int32 command, int32 status``.
* single point result: header + ``int32 status, int32 measMode, int32 isTryMode``
  + 17 doubles: value 1-3, std dev 1-3, std total, pointing error 1-3,
  a-priori std 1-3, a-priori total, temperature, pressure, humidity.
* 6-DoF probe result: header + ``int32 status, int32 rotationStatus, int32
  tipStatus, int32 tipAdapterId, int32 tipAdapterInterface`` + position 1-3,
  quaternion 0-3 (w first), rotation angles x, y, z (doubles). Verify this one
  against the instrument's own header before first use on hardware.
* Lengths are in the unit set on the tracker: millimetres by default
  (``?length_unit=mm``); Cartesian coordinate system assumed.
"""

from __future__ import annotations

import socket
import struct
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.frames import quat_to_matrix
from drivers.readings import Point, Pose
from drivers.roles import PoseTracker
from drivers.tcp_link import TcpLink
from drivers.units import length_factor

EMSCON_PORT = 700
DT_COMMAND, DT_ERROR, DT_SINGLE, DT_PROBE = 0, 1, 2, 11
C_START_MEASUREMENT = 49
HEADERS = {"int32": struct.Struct("<ii"), "int64": struct.Struct("<qI")}
CMD_BODY = struct.Struct("<i")
REPLY_BODY = struct.Struct("<ii")
SINGLE_BODY = struct.Struct("<iii17d")
PROBE_BODY = struct.Struct("<iiiii10d")
MAX_PACKET = 65536
STATUS_NAMES = {1: "server busy", 2: "not implemented", 3: "wrong parameter",
                10014: "system not ready for measurement (beam lost?)",
                10013: "sensor not stable", 28: "no last measured point"}


@dataclass(frozen=True)
class Packet:
    """A decoded emScon packet: type and body bytes (after the header)."""

    type: int
    body: bytes


def encode_packet(ptype: int, body: bytes, header: str = "int32") -> bytes:
    """Prefix ``body`` with the header (size counts the header too)."""
    h = HEADERS[header]
    return h.pack(h.size + len(body), ptype) + body


def decode_header(data: bytes, header: str = "int32") -> tuple[int, int]:
    """Return ``(packet_size, type)``; raise :class:`ProtocolError` on impossible sizes."""
    h = HEADERS[header]
    if len(data) != h.size:
        raise ProtocolError(f"emScon header must be {h.size} bytes")
    size, ptype = h.unpack(data)
    if size < h.size or size > MAX_PACKET:
        raise ProtocolError(f"emScon packet size {size} out of range")
    return size, ptype


def decode_single(body: bytes) -> dict[str, Any]:
    """Decode a single-point result body into status, values and std devs (tracker units)."""
    if len(body) != SINGLE_BODY.size:
        raise ProtocolError(f"single measurement body must be {SINGLE_BODY.size} bytes, "
                            f"got {len(body)}")
    v = SINGLE_BODY.unpack(body)
    return {"status": v[0], "mode": v[1], "try": v[2], "xyz": np.array(v[3:6]),
            "std": np.array(v[6:9]), "std_total": v[9]}


def encode_single(status: int, xyz: np.ndarray, std: np.ndarray) -> bytes:
    """Body of a single-point result (used by the fake)."""
    vals = [*xyz, *std, float(np.linalg.norm(std))] + [0.0] * 3 + [*std, 0.0] + [20.0, 1013.0,
                                                                                  50.0]
    return SINGLE_BODY.pack(status, 0, 0, *vals)


def decode_probe(body: bytes) -> dict[str, Any]:
    """Decode a 6-DoF probe result body: status, position (tracker units), quaternion."""
    if len(body) != PROBE_BODY.size:
        raise ProtocolError(f"probe result body must be {PROBE_BODY.size} bytes, got {len(body)}")
    v = PROBE_BODY.unpack(body)
    q = np.array(v[8:12])
    if not np.all(np.isfinite(q)) or abs(np.linalg.norm(q) - 1) > 1e-3:
        raise ProtocolError(f"probe quaternion {q} is not a unit quaternion")
    return {"status": v[0], "rotation_status": v[1], "xyz": np.array(v[5:8]), "quat": q}


def encode_probe(status: int, xyz: np.ndarray, quat: np.ndarray) -> bytes:
    """Body of a 6-DoF probe result (used by the fake)."""
    return PROBE_BODY.pack(status, 0, 0, 0, 0, *xyz, *quat, 0.0, 0.0, 0.0)


class EmsconTracker(TcpLink, PoseTracker):
    """emScon-style laser tracker client.

    Parameters
    ----------
    address : str
        ``socket://host[:700]``; options ``header`` (``int32``/``int64``),
        ``length_unit`` (default ``mm``).
    """

    peer = "tracker"

    def __init__(self, address: str, *, timeout: float = 5.0, **kwargs: Any) -> None:
        super().__init__(address, timeout=timeout, **kwargs)
        addr = parse_address(address).with_default_port(EMSCON_PORT)
        if addr.scheme != "tcp":
            raise ConnectionFailed(f"{address!r}: expected socket://host:700")
        self.host, self.port = addr.host, int(addr.port or EMSCON_PORT)
        self.header = addr.option("header", "int32") or "int32"
        if self.header not in HEADERS:
            raise ConnectionFailed(f"{address!r}: header must be int32 or int64")
        self.unit = length_factor(addr.option("length_unit", "mm") or "mm")
        self._sock: socket.socket | None = None

    def _read_packet(self) -> Packet:
        size, ptype = decode_header(self._recv_exact(HEADERS[self.header].size), self.header)
        return Packet(ptype, self._recv_exact(size - HEADERS[self.header].size))

    def _measure(self) -> Packet:
        if not self.connected:
            raise ConnectionFailed("not connected")
        if self._sock is None:  # the link was dropped after an error: reconnect once
            self._connect()
        try:
            return self._exchange()
        except (DeviceTimeout, ProtocolError, ConnectionFailed):
            self._close()  # a late or garbled answer must not be read as the next result
            raise

    def _exchange(self) -> Packet:
        try:
            self._sock.sendall(encode_packet(DT_COMMAND, CMD_BODY.pack(C_START_MEASUREMENT),
                                             self.header))
        except OSError as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err
        for _ in range(8):  # command acknowledgement, status packets, then the result
            pkt = self._read_packet()
            if pkt.type in (DT_COMMAND, DT_ERROR):
                if len(pkt.body) != REPLY_BODY.size:
                    raise ProtocolError("command reply must hold command and status")
                command, status = REPLY_BODY.unpack(pkt.body)
                if status != 0:
                    raise DeviceFault(f"tracker refused command {command}: status {status} "
                                      f"({STATUS_NAMES.get(status, 'see ES_ResultStatus')})")
                continue
            if pkt.type in (DT_SINGLE, DT_PROBE):
                return pkt
        raise ProtocolError("no measurement result after the command acknowledgement")

    def _measure_point(self, target: str) -> Point:
        pkt = self._measure()
        if pkt.type != DT_SINGLE:
            raise ProtocolError("expected a single-point result; set the tracker to "
                                "stationary point mode")
        r = decode_single(pkt.body)
        if r["status"] != 0:
            raise DeviceFault(f"measurement status {r['status']}")
        if not np.all(np.isfinite(r["xyz"])):
            raise ProtocolError("non-finite coordinates")
        return Point(value=r["xyz"] * self.unit, sigma=r["std"] * self.unit, target=target,
                     source=self.address)

    def _measure_6dof(self) -> Pose:
        pkt = self._measure()
        if pkt.type != DT_PROBE:
            raise ProtocolError("expected a 6-DoF probe result")
        r = decode_probe(pkt.body)
        if r["status"] != 0:
            raise DeviceFault(f"probe measurement status {r['status']}")
        T = np.eye(4)
        T[:3, :3] = quat_to_matrix(r["quat"])
        T[:3, 3] = r["xyz"] * self.unit
        return Pose(value=T, frame="tracker", child="probe", source=self.address)

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(header=self.header, length_unit_m=self.unit)
        return d
