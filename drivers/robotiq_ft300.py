"""Robotiq FT 300 force/torque sensor over RS-485/USB serial (Modbus RTU and data stream).

Protocol, from the *Robotiq FT 300 Force Torque Sensor Instruction Manual*
(section 4.3 "Communication: Modbus RTU" and "Data stream"):

* Serial link 19200 bit/s, 8 data bits, 1 stop bit, no parity; Modbus slave id 9.
* The stream is started by writing 0x0200 to holding register 410 (Modbus
  function 16): ``09 10 01 9A 00 01 02 02 00 CD CA``; the sensor replies
  ``09 10 01 9A 00 01`` + CRC.
* It then sends 16-byte frames at 100 Hz:
  ``0x20 0x4E`` + six int16 little-endian values + CRC-16/MODBUS (low byte
  first) computed over the first 14 bytes. Fx, Fy, Fz = value / 100 (N);
  Mx, My, Mz = value / 1000 (N m).
* The stream is stopped by sending 0xFF bytes for about 0.5 s (about 50 of them).

Robustness: every read has a timeout; frames with a bad CRC are skipped while
re-synchronising on the next ``0x20 0x4E``; too many bad frames in a row raise
:class:`ProtocolError`.
"""

from __future__ import annotations

import struct
import time
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.modbus import crc16_modbus, encode_write_registers, encode_write_registers_reply
from drivers.roles import ForceTorqueSensor

SLAVE_ID = 9
STREAM_REGISTER = 410
STREAM_START = 0x0200
SYNC = b"\x20\x4e"
FRAME_LEN = 16
SCALE = np.array([1 / 100] * 3 + [1 / 1000] * 3)  # N and N m per count
STOP_BYTES = b"\xff" * 50


def encode_stream_frame(values: np.ndarray) -> bytes:
    """Encode a stream frame from [Fx Fy Fz (N), Mx My Mz (N m)] (used by the fake)."""
    counts = np.clip(np.round(np.asarray(values, float) / SCALE), -32768, 32767).astype(int)
    body = SYNC + struct.pack("<6h", *counts)
    return body + crc16_modbus(body).to_bytes(2, "little")


def decode_stream_frame(frame: bytes) -> np.ndarray:
    """Decode one 16-byte stream frame into [N, N, N, N m, N m, N m].

    Raises
    ------
    ProtocolError
        Wrong length, missing sync bytes, or CRC mismatch.
    """
    if len(frame) != FRAME_LEN:
        raise ProtocolError(f"FT 300 frame must be 16 bytes, got {len(frame)}")
    if frame[:2] != SYNC:
        raise ProtocolError(f"FT 300 frame does not start with 20 4e: {frame[:2].hex(' ')}")
    crc = int.from_bytes(frame[14:], "little")
    if crc16_modbus(frame[:14]) != crc:
        raise ProtocolError("FT 300 frame CRC mismatch")
    return np.array(struct.unpack("<6h", frame[2:14]), dtype=float) * SCALE


class FT300Sensor(ForceTorqueSensor):
    """Robotiq FT 300 in data-stream mode.

    Parameters
    ----------
    address : str
        Serial device, e.g. ``/dev/ttyUSB0?baud=19200``; options ``baud``
        (default 19200) and ``stop_wait`` (s to wait after the stop bytes, default 0.5).
    """

    rate_hz = 100.0
    max_bad_frames = 20

    def __init__(self, address: str, *, timeout: float = 1.0, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address)
        if addr.scheme != "serial":
            raise ConnectionFailed(f"{address!r}: the FT 300 needs a serial port, e.g. "
                                   "/dev/ttyUSB0?baud=19200")
        self.port = addr.path
        self.baud = addr.int_option("baud", 19200)
        self.stop_wait = addr.float_option("stop_wait", 0.5)
        self._ser = None
        self._buf = bytearray()
        self.bad_frames = 0

    def _connect(self) -> None:
        import serial

        try:
            self._ser = serial.serial_for_url(self.port, baudrate=self.baud, bytesize=8,
                                              parity="N", stopbits=1, timeout=0.05)
        except (serial.SerialException, OSError, ValueError) as err:
            raise ConnectionFailed(f"{self.port}: {err}") from err
        try:
            self._ser.write(STOP_BYTES)
            time.sleep(self.stop_wait)
            self._ser.reset_input_buffer()
            self._buf.clear()
            self._ser.write(encode_write_registers(SLAVE_ID, STREAM_REGISTER, [STREAM_START]))
            self._await(encode_write_registers_reply(SLAVE_ID, STREAM_REGISTER, 1))
        except serial.SerialException as err:
            raise ConnectionFailed(f"{self.port}: {err}") from err

    def _await(self, expected: bytes) -> None:
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            self._buf += self._ser.read(64)
            idx = self._buf.find(expected)
            if idx >= 0:
                del self._buf[: idx + len(expected)]
                return
        raise DeviceTimeout(f"{self.port}: FT 300 did not acknowledge the stream start")

    def _close(self) -> None:
        if self._ser is not None:
            try:
                self._ser.write(STOP_BYTES)
            except Exception:  # closing anyway; the port may already be gone
                pass
            self._ser.close()
            self._ser = None

    def _discard_buffered(self) -> None:
        if self._ser is not None:
            self._ser.reset_input_buffer()
            self._buf.clear()

    def _read_sample(self) -> np.ndarray:
        import serial

        if self._ser is None:
            raise ConnectionFailed("not connected")
        deadline = time.monotonic() + self.timeout
        bad = 0
        while True:
            idx = self._buf.find(SYNC)
            if idx < 0:
                del self._buf[:-1]
            else:
                del self._buf[:idx]
                if len(self._buf) >= FRAME_LEN:
                    frame = bytes(self._buf[:FRAME_LEN])
                    try:
                        values = decode_stream_frame(frame)
                    except ProtocolError:
                        bad += 1
                        self.bad_frames += 1
                        del self._buf[:1]  # resynchronise on the next 20 4e
                        if bad >= self.max_bad_frames:
                            raise
                        continue
                    del self._buf[:FRAME_LEN]
                    counts = struct.unpack("<6h", frame[2:14])
                    if any(c in (-32768, 32767) for c in counts):
                        raise DeviceFault("FT 300 reading saturated (outside its range): "
                                          f"{np.round(values, 3).tolist()}")
                    return values
            if time.monotonic() > deadline:
                raise DeviceTimeout(f"{self.port}: no valid FT 300 frame in {self.timeout} s")
            try:
                self._buf += self._ser.read(max(FRAME_LEN, self._ser.in_waiting))
            except (serial.SerialException, OSError) as err:
                raise ConnectionFailed(f"{self.port}: {err}") from err

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(baud=self.baud, resolution=[0.01, 0.01, 0.01, 0.001, 0.001, 0.001])
        return d
