"""ATI Net F/T (and Axia) force/torque sensor over RDT (UDP) with calibration read over HTTP.

Protocol, from ATI's *Net F/T Installation and Operation Manual* (9620-05-NET FT),
section "Raw Data Transfer (RDT)" and section "netftapi2.xml / calibration page":

* The host sends an 8-byte request to UDP port 49152, big-endian:
  ``uint16 header = 0x1234``, ``uint16 command``, ``uint32 sample_count``
  (0 = stream until told to stop). Commands used here: 0x0000 stop streaming,
  0x0002 start high-speed real-time streaming, 0x0042 set software bias.
* The sensor answers with 36-byte records, big-endian: ``uint32 rdt_sequence``,
  ``uint32 ft_sequence``, ``uint32 status``, then ``int32`` Fx Fy Fz Tx Ty Tz in
  counts. Force = counts / counts-per-force, torque = counts / counts-per-torque,
  in the units configured on the sensor.
* ``http://<sensor>/netftapi2.xml`` holds the active configuration: ``cfgcpf``
  (counts per force), ``cfgcpt`` (counts per torque), ``scfgfu`` and
  ``scfgtu`` (unit names, e.g. ``N`` and ``Nm``).
* A non-zero ``status`` word reports a sensor fault (manual, "System Status Code").

Robustness: every receive has a timeout; records whose ``rdt_sequence`` is not
newer than the last one (late or duplicated datagrams) are dropped; datagrams of
the wrong length are counted and skipped, and too many in a row raise
:class:`ProtocolError`.
"""

from __future__ import annotations

import socket
import struct
import time
import urllib.error
import urllib.request
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.roles import ForceTorqueSensor
from drivers.units import force_factor, torque_factor

RDT_PORT = 49152
RDT_HEADER = 0x1234
CMD_STOP = 0x0000
CMD_START_REALTIME = 0x0002
CMD_SET_BIAS = 0x0042
RECORD = struct.Struct(">III6i")
REQUEST = struct.Struct(">HHI")


@dataclass(frozen=True)
class RdtRecord:
    """One decoded RDT record (counts, not yet scaled)."""

    rdt_sequence: int
    ft_sequence: int
    status: int
    counts: tuple[int, int, int, int, int, int]


@dataclass(frozen=True)
class NetFTCalibration:
    """Scaling read from ``netftapi2.xml``: counts per unit and the sensor's unit names."""

    counts_per_force: float
    counts_per_torque: float
    force_unit: str = "N"
    torque_unit: str = "Nm"

    def scale(self) -> np.ndarray:
        """Multipliers (N per count, N m per count) for the six channels."""
        f = force_factor(self.force_unit) / self.counts_per_force
        t = torque_factor(self.torque_unit) / self.counts_per_torque
        return np.array([f, f, f, t, t, t])


def encode_request(command: int, sample_count: int = 0) -> bytes:
    """Encode an RDT request (8 bytes, big-endian)."""
    return REQUEST.pack(RDT_HEADER, command, sample_count)


def decode_request(data: bytes) -> tuple[int, int]:
    """Decode an RDT request into ``(command, sample_count)``; used by the fake sensor."""
    if len(data) != REQUEST.size:
        raise ProtocolError(f"RDT request must be 8 bytes, got {len(data)}")
    header, command, count = REQUEST.unpack(data)
    if header != RDT_HEADER:
        raise ProtocolError(f"RDT request header 0x{header:04x} is not 0x1234")
    return command, count


def encode_record(rec: RdtRecord) -> bytes:
    """Encode one 36-byte RDT record."""
    return RECORD.pack(rec.rdt_sequence, rec.ft_sequence, rec.status, *rec.counts)


def decode_records(data: bytes) -> list[RdtRecord]:
    """Decode a datagram holding one or more 36-byte RDT records.

    Raises
    ------
    ProtocolError
        If the length is not a positive multiple of 36 bytes.
    """
    if len(data) == 0 or len(data) % RECORD.size:
        raise ProtocolError(f"RDT datagram of {len(data)} bytes is not a multiple of 36")
    out = []
    for off in range(0, len(data), RECORD.size):
        seq, ftseq, status, *counts = RECORD.unpack_from(data, off)
        out.append(RdtRecord(seq, ftseq, status, tuple(counts)))
    return out


def parse_calibration_xml(text: bytes | str) -> NetFTCalibration:
    """Read counts per force/torque and unit names from ``netftapi2.xml``.

    Raises
    ------
    ProtocolError
        If the XML is malformed or lacks ``cfgcpf``/``cfgcpt``.
    """
    try:
        root = ET.fromstring(text)
    except ET.ParseError as err:
        raise ProtocolError(f"calibration page is not XML: {err}") from err
    def field(name: str) -> str | None:
        node = root.find(f".//{name}")
        return node.text.strip() if node is not None and node.text else None
    cpf, cpt = field("cfgcpf"), field("cfgcpt")
    if cpf is None or cpt is None:
        raise ProtocolError("calibration page lacks cfgcpf/cfgcpt")
    try:
        cal = NetFTCalibration(float(cpf), float(cpt), field("scfgfu") or "N",
                               field("scfgtu") or "Nm")
    except ValueError as err:
        raise ProtocolError(f"calibration counts are not numbers: {cpf!r}, {cpt!r}") from err
    if not (cal.counts_per_force > 0 and cal.counts_per_torque > 0):
        raise ProtocolError("calibration counts per unit must be positive")
    cal.scale()  # unknown unit names raise here, at connect time
    return cal


def fetch_calibration(host: str, port: int = 80, timeout: float = 2.0) -> NetFTCalibration:
    """HTTP GET ``/netftapi2.xml`` from the sensor and parse it."""
    url = f"http://{host}:{port}/netftapi2.xml"
    try:
        with urllib.request.urlopen(url, timeout=timeout) as resp:  # noqa: S310 (http by design)
            body = resp.read(1_000_000)
    except TimeoutError as err:
        raise DeviceTimeout(f"{url}: no answer within {timeout} s") from err
    except (urllib.error.URLError, OSError) as err:
        raise ConnectionFailed(f"{url}: {err}") from err
    return parse_calibration_xml(body)


class NetFTSensor(ForceTorqueSensor):
    """ATI Net F/T over RDT.

    Parameters
    ----------
    address : str
        ``udp://host[:49152]``; options ``http_port`` (default 80),
        ``cpf``/``cpt`` to override the calibration page.
    timeout : float
        Seconds to wait for any one record.
    """

    rate_hz = 1000.0
    max_bad_datagrams = 20

    def __init__(self, address: str, *, timeout: float = 1.0, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address).with_default_port(RDT_PORT)
        if addr.scheme != "udp":
            raise ConnectionFailed(f"{address!r}: the Net F/T speaks RDT over udp://host:port")
        self.host, self.port = addr.host, int(addr.port or RDT_PORT)
        self.http_port = addr.int_option("http_port", 80)
        self._override = (addr.options.get("cpf"), addr.options.get("cpt"))
        self.calibration: NetFTCalibration | None = None
        self._sock: socket.socket | None = None
        self._last_seq: int | None = None
        self.dropped = 0  # sequence gaps seen (datagrams lost)
        self.discarded = 0  # late, duplicated or malformed datagrams ignored
        self.restarts = 0  # start requests re-sent after silence

    def _connect(self) -> None:
        if all(self._override):
            self.calibration = NetFTCalibration(float(self._override[0]), float(self._override[1]))
        else:
            self.calibration = fetch_calibration(self.host, self.http_port, self.timeout)
        self._scale = self.calibration.scale()
        try:
            sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            sock.settimeout(self.timeout)
            sock.connect((self.host, self.port))
            sock.send(encode_request(CMD_START_REALTIME, 0))
        except OSError as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err
        self._sock = sock
        self._last_seq = None

    def _close(self) -> None:
        if self._sock is not None:
            try:
                self._sock.send(encode_request(CMD_STOP, 0))
            except OSError:
                pass
            self._sock.close()
            self._sock = None

    def _read_sample(self) -> np.ndarray:
        if self._sock is None:
            raise ConnectionFailed("not connected")
        deadline = time.monotonic() + self.timeout
        restart_at: float | None = time.monotonic() + self.timeout / 2
        bad = old = 0
        while True:
            if restart_at is not None and time.monotonic() > restart_at:
                restart_at = None  # once per read: the sensor may have rebooted or lost us
                self.restarts += 1
                try:
                    self._sock.send(encode_request(CMD_START_REALTIME, 0))
                except OSError as err:
                    raise ConnectionFailed(f"{self.address}: {err}") from err
            left = deadline - time.monotonic()
            if left <= 0:
                if bad:
                    raise ProtocolError(f"{bad} malformed datagrams and no good record in "
                                        f"{self.timeout} s")
                raise DeviceTimeout(f"{self.address}: no RDT record within {self.timeout} s")
            if restart_at is not None:
                left = max(1e-3, min(left, restart_at - time.monotonic()))
            self._sock.settimeout(left)
            try:
                data = self._sock.recv(2048)
            except TimeoutError:
                continue
            except OSError as err:  # e.g. ICMP port unreachable
                raise ConnectionFailed(f"{self.address}: {err}") from err
            try:
                records = decode_records(data)
            except ProtocolError:
                bad += 1
                self.discarded += 1
                if bad >= self.max_bad_datagrams:
                    raise
                continue
            rec = records[-1]
            if self._last_seq is not None:
                step = (rec.rdt_sequence - self._last_seq) & 0xFFFFFFFF
                if step == 0 or step > 0x7FFFFFFF:  # duplicate or older: late datagram
                    old += 1
                    if old < self.max_bad_datagrams:
                        self.discarded += 1
                        continue
                    step = 1  # a long run of "older" records: the sensor restarted its count
                self.dropped += step - 1
            self._last_seq = rec.rdt_sequence
            if rec.status != 0:
                raise DeviceFault(f"Net F/T status word 0x{rec.status:08x} reports a fault")
            if any(c in (-(2**31), 2**31 - 1) for c in rec.counts):
                raise DeviceFault("Net F/T counts at the int32 limit: reading saturated")
            return np.asarray(rec.counts, dtype=float) * self._scale

    def _discard_buffered(self) -> None:
        if self._sock is None:
            return
        self._sock.setblocking(False)
        try:
            while True:
                self._sock.recv(2048)
        except (BlockingIOError, OSError):
            pass
        finally:
            self._sock.settimeout(self.timeout)

    def set_hardware_bias(self) -> None:
        """Ask the sensor to zero itself (RDT command 0x0042)."""
        if self._sock is None:
            raise ConnectionFailed("not connected")
        try:
            self._sock.send(encode_request(CMD_SET_BIAS, 0))
        except OSError as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        if self.calibration is not None:
            d.update(counts_per_force=self.calibration.counts_per_force,
                     counts_per_torque=self.calibration.counts_per_torque,
                     sensor_units=[self.calibration.force_unit, self.calibration.torque_unit])
        return d
