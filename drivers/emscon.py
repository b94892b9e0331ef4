"""Laser tracker over Leica emScon binary packets on TCP (port 700).

Packet layouts checked against Leica's emScon TPI C header ``ES_C_API_Def.h``
(TPI/SDK V3.6, the full all-tracker-types edition; public copy in the GitHub
repository ``beckjac/emscon_ros``, ``include/emscon_ros/ES_C_API_Def.h``, with
its ``ES_CPP_API_Def.h`` for the packet dispatch; the AT4xx-only extract in
``MuffinSpawn/Leica``, ``Include/ES_C_API_Def.h``, agrees on every 3D item).
Structures used: ``PacketHeaderT``, ``ReturnDataT``, ``BasicCommandCT/RT``,
``ErrorResponseT``, ``SingleMeasResultT``, ``ProbeStationaryResultT`` and
``ProbePosResultT``. The header packs with ``#pragma pack(4)``; ``int``,
``long`` and every ``enum`` are 4 bytes with the Windows compilers emScon
targets; little-endian. Sizes below were confirmed with ``sizeof``/``offsetof``
on that header (``long`` forced to 4 bytes).

* header (``PacketHeaderT``, 8 bytes): ``long lPacketSize`` (whole packet,
  bytes) and ``enum ES_DataType type``. ES_DataType: 0 command, 1 error,
  2 single measurement, 3 multi measurement, 4 stationary probe (6-DoF)
  measurement, 5 continuous probe measurement, 6 nivel, 7 reflector position,
  8 system status change, 9 single measurement 2 (extended statistics),
  10 multi measurement 2, 11 probe position.
  **Header layout is an option**: the C header gives ``int32 size, int32 type``
  (``header="int32"``, default); the community CESAPI Python package packs
  ``int64 size, uint32 type`` (``header="int64"``). Choose with ``?header=int64``.
* command (``BasicCommandCT``): header + ``int32 command``
  (ES_C_StartMeasurement = 49); answer (``BasicCommandRT``): header + ``int32
  command, int32 status`` (ES_ResultStatus, 0 = all OK). Error
  (``ErrorResponseT``) has the same body.
* single point result (``SingleMeasResultT``, type 2, 156 bytes): header +
  ``int32 status, measMode, bIsTryMode`` + 17 doubles: value 1-3, std dev 1-3,
  std total, pointing error 1-3, a-priori std 1-3, a-priori total, temperature,
  pressure, humidity.
* 6-DoF result of StartMeasurement in ES_MM_6DStationary mode
  (``ProbeStationaryResultT``, type 4, 376 bytes): header + 10 int32 (status,
  measMode, bIsTryMode, triggerStatus, lRotationStatus, iInternalProbeId,
  iFieldNumber, tipStatus, iInternalTipAdapterId, iTipAdapterInterface) +
  41 doubles: position 1-3, std dev 1-3 and total, covariance 12/13/23,
  a-priori std dev 1-3 and total, a-priori covariance 12/13/23, quaternion
  0-3, rotation angles x/y/z, their std devs x/y/z and total, covariances
  xy/xz/yz, a-priori std devs x/y/z and total, a-priori covariances xy/xz/yz,
  temperature, pressure, humidity.
* ``ProbePosResultT`` (type 11, 108 bytes: header + status, lRotationStatus,
  tipStatus, tip adapter id and interface + position 1-3, quaternion 0-3,
  rotation angles x/y/z) is the unsolicited probe position indication (like
  ``ReflectorPosResultT``, type 7), not a measurement: skipped while waiting.
* ``lRotationStatus`` is the ``RotationStatus`` bit field; with the LSB-first
  allocation of MSVC, bit 0 = 6D status valid and bit 1 = 6D error.
* Not stated in the header, assumed: quaternion 0 is the scalar part (w, x, y,
  z) and rotates probe coordinates into the tracker frame (this file uses the
  quaternion only, never the rotation angles, whose convention is undocumented
  there). Lengths are in the unit set on the tracker: millimetres by default
  (``?length_unit=mm``); Cartesian coordinate system assumed. Extended
  statistic mode (type 9 results) is refused with a clear error.
"""

from __future__ import annotations

import socket
import struct
import time
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
# ES_DataType values (ES_C_API_Def.h)
DT_COMMAND, DT_ERROR, DT_SINGLE, DT_PROBE_STATIONARY = 0, 1, 2, 4
DT_REFLECTOR_POS, DT_STATUS_CHANGE, DT_SINGLE2, DT_PROBE_POS = 7, 8, 9, 11
C_START_MEASUREMENT = 49
HEADERS = {"int32": struct.Struct("<ii"), "int64": struct.Struct("<qI")}
CMD_BODY = struct.Struct("<i")
REPLY_BODY = struct.Struct("<ii")
SINGLE_BODY = struct.Struct("<iii17d")
PROBE_BODY = struct.Struct("<10i41d")  # ProbeStationaryResultT after the header
PROBE_POS_BODY = struct.Struct("<5i10d")  # ProbePosResultT after the header
ROT_STATUS_VALID, ROT_STATUS_ERROR = 0x1, 0x2  # RotationStatus bits Status6D, Error6D
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
    """Decode a 6-DoF stationary probe result body (``ProbeStationaryResultT``).

    Returns the status words, position with its std devs and covariances
    (tracker units), quaternion (w, x, y, z), rotation angles with their std
    devs (tracker angle unit) and the environment values.
    """
    if len(body) != PROBE_BODY.size:
        raise ProtocolError(f"probe result body must be {PROBE_BODY.size} bytes, got {len(body)}")
    v = PROBE_BODY.unpack(body)
    d = np.array(v[10:])
    q = d[17:21]
    if not np.all(np.abs(q) <= 1.001) or abs(np.linalg.norm(q) - 1) > 1e-3:  # NaN fails too
        raise ProtocolError(f"probe quaternion {q} is not a unit quaternion")
    return {"status": v[0], "mode": v[1], "try": v[2], "trigger": v[3],
            "rotation_status": v[4], "probe_id": v[5], "field": v[6], "tip_status": v[7],
            "tip_adapter_id": v[8], "tip_adapter_interface": v[9],
            "xyz": d[0:3], "std": d[3:6], "std_total": d[6], "cov": d[7:10],
            "apriori_std": d[10:13], "apriori_std_total": d[13], "apriori_cov": d[14:17],
            "quat": q, "angles": d[21:24], "std_angles": d[24:27], "std_angles_total": d[27],
            "cov_angles": d[28:31], "temperature": d[-3], "pressure": d[-2], "humidity": d[-1]}


def encode_probe(status: int, xyz: np.ndarray, quat: np.ndarray, std: np.ndarray | None = None,
                 rotation_status: int = ROT_STATUS_VALID, angles: np.ndarray | None = None,
                 std_angles: np.ndarray | None = None) -> bytes:
    """Body of a 6-DoF stationary probe result (used by the fake); unset values are 0."""
    std = np.zeros(3) if std is None else np.asarray(std, dtype=float)
    angles = np.zeros(3) if angles is None else angles
    std_angles = np.zeros(3) if std_angles is None else np.asarray(std_angles, dtype=float)
    position = [*xyz, *std, float(np.linalg.norm(std)), 0.0, 0.0, 0.0,
                *std, float(np.linalg.norm(std)), 0.0, 0.0, 0.0]
    rotation = [*quat, *angles, *std_angles, float(np.linalg.norm(std_angles)), 0.0, 0.0, 0.0,
                *std_angles, float(np.linalg.norm(std_angles)), 0.0, 0.0, 0.0]
    ints = (status, 6, 0, 0, rotation_status, 0, 0, 0, 0, 0)  # measMode ES_MM_6DStationary
    return PROBE_BODY.pack(*ints, *position, *rotation, 20.0, 1013.0, 50.0)


def encode_probe_position(xyz: np.ndarray, quat: np.ndarray) -> bytes:
    """Body of an unsolicited probe position packet (``ProbePosResultT``; used by the fake)."""
    return PROBE_POS_BODY.pack(0, ROT_STATUS_VALID, 0, 0, 0, *xyz, *quat, 0.0, 0.0, 0.0)


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
        except (DeviceTimeout, ProtocolError, ConnectionFailed, KeyboardInterrupt):
            # a late or garbled answer (or one still coming after a Ctrl-C) must not be
            # read as the next result
            self._close()
            raise

    def _exchange(self) -> Packet:
        try:
            self._sock.sendall(encode_packet(DT_COMMAND, CMD_BODY.pack(C_START_MEASUREMENT),
                                             self.header))
        except OSError as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err
        # command acknowledgement, then the result; unsolicited position and status
        # packets may come in between and are skipped until the timeout runs out
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            pkt = self._read_packet()
            if pkt.type in (DT_COMMAND, DT_ERROR):
                if len(pkt.body) != REPLY_BODY.size:
                    raise ProtocolError("command reply must hold command and status")
                command, status = REPLY_BODY.unpack(pkt.body)
                if status != 0:
                    raise DeviceFault(f"tracker refused command {command}: status {status} "
                                      f"({STATUS_NAMES.get(status, 'see ES_ResultStatus')})")
                continue
            if pkt.type in (DT_SINGLE, DT_PROBE_STATIONARY):
                return pkt
            if pkt.type == DT_SINGLE2:
                raise ProtocolError("got an extended-statistics result (SingleMeasResult2T); "
                                    "set the statistic mode to standard")
        raise DeviceTimeout(f"{self.address}: no measurement result within {self.timeout} s")

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
        if pkt.type != DT_PROBE_STATIONARY:
            raise ProtocolError("expected a 6-DoF stationary probe result; set the tracker to "
                                "6D stationary mode")
        r = decode_probe(pkt.body)
        if r["status"] != 0:
            raise DeviceFault(f"probe measurement status {r['status']} "
                              f"({STATUS_NAMES.get(r['status'], 'see ES_ResultStatus')})")
        if r["rotation_status"] & ROT_STATUS_ERROR:
            raise DeviceFault(f"probe 6D rotation status reports an error "
                              f"(0x{r['rotation_status']:08x})")
        T = np.eye(4)
        T[:3, :3] = quat_to_matrix(r["quat"])
        T[:3, 3] = r["xyz"] * self.unit
        return Pose(value=T, frame="tracker", child="probe", source=self.address)

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(header=self.header, length_unit_m=self.unit)
        return d
