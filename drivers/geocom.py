"""ASCII GeoCOM-style request/reply instrument (total station / tracker) over serial or TCP.

Protocol from Leica's *TPS1200 GeoCOM Reference Manual* (section 2 "ASCII
protocol", and RPC descriptions in the TMC chapter):

* request ``%R1Q,<RPC>[,<TrId>]:<p1>,<p2>...`` + CR/LF; reply
  ``%R1P,0,<TrId>:<RC>,<v1>,<v2>...`` + CR/LF, where ``RC`` 0 means GRC_OK and
  the transaction id ``TrId`` echoes the request's. The driver numbers its
  requests 1..7 in turn and ignores replies with another id; the id of a request
  that timed out is not reused until its late reply has come (and been dropped)
  or ``LATE_HORIZON_S`` has passed, so a late reply to an earlier, timed-out
  request is never taken for the current one, even 7 or 14 requests later.
* RPC 2008 ``TMC_DoMeasure(Command, Mode)`` triggers a distance measurement
  (Command 1 = TMC_DEF_DIST, Mode 1 = TMC_AUTO_INC).
* RPC 2082 ``TMC_GetCoordinate(WaitTime [ms], Mode)`` returns ``E, N, H`` (m),
  the coordinate time, and the continuous-mode ``E, N, H`` and time.
* Any non-zero return code is refused (including the warnings 1283/1284 whose
  accuracy is not guaranteed, and 1285 "angle only, no distance" when the beam
  is lost), so a doubtful coordinate is never passed on as good.

Transport: any pyserial URL, e.g. ``/dev/ttyUSB0?baud=19200`` or ``socket://host:port``.
"""

from __future__ import annotations

import re
import time
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.readings import Point
from drivers.roles import PoseTracker

RPC_DO_MEASURE = 2008
RPC_GET_COORDINATE = 2082
RC_NAMES = {1283: "TMC_NO_FULL_CORRECTION", 1284: "TMC_ACCURACY_GUARANTEE",
            1285: "TMC_ANGLE_OK (no distance: beam lost?)", 1292: "TMC_BUSY",
            8710: "AUT_NO_TARGET"}
#: transaction ids used in turn (1..7)
TRIDS = 7
#: s, after which a timed-out request's id is reused although its reply never came (taken
#: as lost: the fake's late replies come 1.5 s late, an instrument's within its WaitTime)
LATE_HORIZON_S = 30.0
_REPLY = re.compile(r"^%R1P,(\d+),(\d+):(-?\d+)?((?:,[^,]*)*)$")


def encode_request(rpc: int, *params: object, trid: int | None = None) -> bytes:
    """``%R1Q,<rpc>[,<trid>]:<params>`` + CR/LF."""
    head = f"%R1Q,{rpc}" if trid is None else f"%R1Q,{rpc},{trid}"
    return f"{head}:{','.join(str(p) for p in params)}\r\n".encode("ascii")


def decode_request(line: bytes) -> tuple[int, list[str], int]:
    """Parse a request line (used by the fake); returns ``(rpc, params, trid)``."""
    text = line.decode("ascii", "replace").strip()
    m = re.match(r"^%R1Q,(\d+)(?:,(\d+))?:(.*)$", text)
    if not m:
        raise ProtocolError(f"not a GeoCOM request: {text[:40]!r}")
    params = m.group(3).split(",") if m.group(3) else []
    return int(m.group(1)), params, int(m.group(2) or 0)


def encode_reply(rc: int, *values: object, trid: int = 0) -> bytes:
    """``%R1P,0,<trid>:<rc>,<values>`` + CR/LF."""
    tail = "".join(f",{v}" for v in values)
    return f"%R1P,0,{trid}:{rc}{tail}\r\n".encode("ascii")


def decode_reply(line: bytes) -> tuple[int, list[str]]:
    """Parse a reply line into ``(rc, values)`` (see :func:`reply_trid` for its id).

    Raises
    ------
    ProtocolError
        If the line is not ASCII or does not follow ``%R1P,0,n:rc,...``.
    """
    try:
        text = line.decode("ascii").strip()
    except UnicodeDecodeError as err:
        raise ProtocolError("GeoCOM reply is not ASCII") from err
    m = _REPLY.match(text)
    if not m:
        raise ProtocolError(f"malformed GeoCOM reply {text[:60]!r}")
    if m.group(1) != "0":
        raise ProtocolError(f"GeoCOM communication error code {m.group(1)}")
    if m.group(3) is None:
        raise ProtocolError(f"GeoCOM reply without a return code: {text[:60]!r}")
    values = m.group(4)[1:].split(",") if m.group(4) else []
    return int(m.group(3)), values


def reply_trid(line: bytes) -> int | None:
    """Transaction id of a reply line, or None if it has none readable."""
    m = re.match(rb"^%R1P,\d+,(\d+):", line.strip())
    return int(m.group(1)) if m else None


class GeoComTracker(PoseTracker):
    """GeoCOM-style instrument measuring reflector coordinates (m).

    Parameters
    ----------
    address : str
        pyserial URL: ``/dev/ttyUSB0?baud=19200`` or ``socket://host:port``.
    """

    def __init__(self, address: str, *, timeout: float = 5.0, **kwargs: Any) -> None:
        super().__init__(address, timeout=timeout, **kwargs)
        addr = parse_address(address)
        if addr.scheme == "serial":
            self.url, self.baud = addr.path, addr.int_option("baud", 19200)
        elif addr.scheme == "tcp":
            self.url, self.baud = f"socket://{addr.host}:{addr.port}", 19200
        else:
            raise ConnectionFailed(f"{address!r}: expected a serial port or socket://host:port")
        self._ser = None
        self._trid = 0
        #: ids of timed-out requests whose late reply may still come -> when to reuse them
        self._abandoned: dict[int, float] = {}
        self.stale_replies = 0

    def _connect(self) -> None:
        import serial

        try:
            self._ser = serial.serial_for_url(self.url, baudrate=self.baud, timeout=0.1)
        except (serial.SerialException, OSError, ValueError) as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err

    def _close(self) -> None:
        if self._ser is not None:
            self._ser.close()
            self._ser = None

    def call(self, rpc: int, *params: object) -> list[str]:
        """Send one RPC and return its values; non-zero RC raises :class:`DeviceFault`."""
        import serial

        if self._ser is None:
            raise ConnectionFailed("not connected")
        self._trid = self._next_trid()
        try:
            self._ser.reset_input_buffer()
            # the leading LF clears the instrument's receive buffer (manual, section 2.2:
            # "[<LF>]%R1Q,..."), so a partial request left by an earlier failure is dropped
            self._ser.write(b"\n" + encode_request(rpc, *params, trid=self._trid))
            deadline = time.monotonic() + self.timeout
            line = b""
            while True:
                if time.monotonic() > deadline:
                    # its reply may still come: the id is not reused until then
                    self._abandoned[self._trid] = time.monotonic() + LATE_HORIZON_S
                    raise DeviceTimeout(f"{self.address}: no reply to RPC {rpc}")
                line += self._ser.read_until(b"\n", 512 - len(line))
                if len(line) >= 512:
                    raise ProtocolError("GeoCOM reply longer than 512 bytes")
                if line.endswith(b"\n"):
                    if not line.strip():
                        line = b""  # a stray terminator: not a reply
                        continue
                    # a partial line before the reply (an earlier reply cut short, line
                    # noise) runs into it: the reply starts at its last "%R1P"
                    start = line.rfind(b"%R1P")
                    if start > 0:
                        line = line[start:]
                    trid = reply_trid(line)
                    if trid is None or trid == self._trid:
                        break
                    self.stale_replies += 1  # late answer to an earlier request
                    self._abandoned.pop(trid, None)  # it came: its id is free again
                    line = b""
        except serial.SerialException as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err
        rc, values = decode_reply(line)
        if rc != 0:
            raise DeviceFault(f"RPC {rpc} returned {rc} ({RC_NAMES.get(rc, 'see GeoCOM manual')})")
        return values

    def _next_trid(self) -> int:
        """The next id in turn (1..7) that no timed-out request may still answer to."""
        now = time.monotonic()
        self._abandoned = {t: until for t, until in self._abandoned.items() if until > now}
        for step in range(1, TRIDS + 1):
            trid = (self._trid + step - 1) % TRIDS + 1
            if trid not in self._abandoned:
                return trid
        raise DeviceTimeout(f"{self.address}: {TRIDS} requests unanswered in the last "
                            f"{LATE_HORIZON_S:.0f} s (ids 1-{TRIDS} may all still get late "
                            "replies); check the instrument and its link")

    def _measure_point(self, target: str) -> Point:
        self.call(RPC_DO_MEASURE, 1, 1)
        values = self.call(RPC_GET_COORDINATE, int(self.timeout * 1000), 1)
        if len(values) < 3:
            raise ProtocolError(f"TMC_GetCoordinate returned {len(values)} values, expected >= 3")
        try:
            xyz = np.array([float(v) for v in values[:3]])
        except ValueError as err:
            raise ProtocolError(f"non-numeric coordinates {values[:3]}") from err
        if not np.all(np.isfinite(xyz)):
            raise ProtocolError("non-finite coordinates")
        return Point(value=xyz, target=target, source=self.address)
