"""Fake Robotiq FT 300 on a pseudo-terminal: Modbus RTU register map, 100 Hz stream, 0xFF stop.

What it implements, from the *Robotiq FT 300 Instruction Manual* (section 4.3,
"Communication: Modbus RTU" and "Data stream"); see also drivers/README.md:

* Modbus RTU slave 9 (19200 8N1 on the real sensor), CRC-16/MODBUS. Functions 3 and 4
  read the register map: 180-185 Fx, Fy, Fz (N x 100), Mx, My, Mz (N m x 1000),
  190-192 acceleration (g x 1000), 510-513 serial number, 514 production year (all
  int16/uint16). Function 16 writing 0x0200 to register 410 starts the stream.
* Exception replies for anything else: 01 illegal function (other function codes),
  02 illegal data address (a register outside the map, a write elsewhere than 410),
  03 illegal data value (a count of 0 or above 125, another value written to 410).
  Requests to another slave id, or with a bad CRC, get no answer (as on a bus); bytes
  that do not complete a request are dropped after a silence of :data:`SILENCE` s (the
  RTU end of frame, 3.5 characters on a wire, made longer for pty scheduling).
* While streaming, 16-byte frames ``20 4E`` + six int16 (little-endian) + CRC at
  100 Hz (faster in a sped-up lab: :func:`stream_rate`); the sensor then ignores Modbus
  requests, and any 0xFF byte stops the stream (the manual: send 0xFF for about 0.5 s).
  Leading 0xFF bytes are skipped.
* Assumed (the manual gives only the register numbers): the serial number is
  8 ASCII characters, two per register, first character in the high byte.
"""

from __future__ import annotations

import os
import select
import struct
import time
import tty

import numpy as np

from drivers import modbus
from drivers.errors import ProtocolError
from drivers.modbus import (
    ILLEGAL_DATA_ADDRESS,
    ILLEGAL_DATA_VALUE,
    ILLEGAL_FUNCTION,
    crc16_modbus,
    decode_write_registers_request,
    encode_exception,
    encode_read_reply,
    encode_write_registers_reply,
)
from drivers.robotiq_ft300 import (
    SCALE,
    SLAVE_ID,
    STREAM_REGISTER,
    STREAM_START,
    encode_stream_frame,
)
from drivers.sim.base import FakeServer
from drivers.sim.world import World

SERIAL_NUMBER = "FT300SIM"  # registers 510-513
PRODUCTION_YEAR = 2016  # register 514
FT_REGISTERS = range(180, 186)
ACCEL_REGISTERS = range(190, 193)
ID_REGISTERS = range(510, 515)
SILENCE = 0.05  # s without a byte that ends a frame
#: the sensor's stream rate (Hz of simulated time)
STREAM_HZ = 100.0
#: the stream follows the lab's time scale up to this speed-up (1 kHz of 16-byte frames
#: through a pty is far within one thread's reach; faster would only load the machine)
MAX_SPEEDUP = 10.0


def stream_rate(time_scale: float) -> float:
    """Wall-clock stream rate (Hz) of a lab whose simulated time runs ``time_scale``
    times faster than the wall clock: 100 Hz of simulated time, within 100 Hz .. 1 kHz."""
    return STREAM_HZ * min(max(time_scale, 1.0), MAX_SPEEDUP)


def _int16(values: np.ndarray) -> list[int]:
    return [int(v) & 0xFFFF for v in np.clip(np.round(values), -32768, 32767)]


class FakeFT300(FakeServer):
    """Serves the FT 300 protocol on the master side of a pty; the driver opens the slave."""

    driver = "robotiq-ft300"
    device = "robotiq-ft300"

    def __init__(self, world: World, rate_hz: float = STREAM_HZ) -> None:
        super().__init__(world)
        self.rate_hz = rate_hz
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        tty.setraw(self.master)
        os.set_blocking(self.master, False)
        self.path = os.ttyname(self.slave)
        self.url = f"{self.path}?baud=19200&stop_wait=0.05"
        self.streaming = False
        self._last = None

    def _close(self) -> None:
        pass

    def _send(self, data: bytes) -> None:
        try:
            os.write(self.master, data)
        except (BlockingIOError, OSError):
            pass  # nobody reading: the line drops the bytes, like a real UART

    # --- register map -----------------------------------------------------
    def register(self, address: int) -> int | None:
        """Value (uint16) of one register of the map, None outside it."""
        if address in FT_REGISTERS:
            counts = self.world.sensor_wrench(self.device) / SCALE
            return _int16(counts)[address - FT_REGISTERS.start]
        if address in ACCEL_REGISTERS:
            # an accelerometer at rest reads +1 g along the upward vertical
            T = self.world.true_tool_pose() @ self.world.sensor_mount
            up = T[:3, :3].T @ np.array([0.0, 0.0, 1.0])
            return _int16(up * 1000)[address - ACCEL_REGISTERS.start]
        if address in range(510, 514):
            pair = SERIAL_NUMBER[2 * (address - 510): 2 * (address - 510) + 2].encode("ascii")
            return (pair[0] << 8) | pair[1]
        if address == 514:
            return PRODUCTION_YEAR
        return None

    def _read_registers(self, frame: bytes) -> bytes:
        slave, function, first, count = struct.unpack(">BBHH", frame[:6])
        if not 1 <= count <= 125:
            return encode_exception(slave, function, ILLEGAL_DATA_VALUE)
        if function in (3, 4) and first in FT_REGISTERS and first + count <= FT_REGISTERS.stop:
            # one sample for the whole block, as the sensor latches its registers
            counts = _int16(self.world.sensor_wrench(self.device) / SCALE)
            return encode_read_reply(slave, function, counts[first - 180:first - 180 + count])
        values = [self.register(a) for a in range(first, first + count)]
        if any(v is None for v in values):
            return encode_exception(slave, function, ILLEGAL_DATA_ADDRESS)
        return encode_read_reply(slave, function, values)

    def _answer(self, frame: bytes) -> bytes | None:
        """Reply to one CRC-checked request addressed to this slave."""
        function = frame[1]
        if function in (3, 4):
            return self._read_registers(frame)
        if function == 16:
            try:
                slave, first, values = decode_write_registers_request(frame)
            except ProtocolError:
                return encode_exception(frame[0], function, ILLEGAL_DATA_VALUE)
            if first != STREAM_REGISTER or len(values) != 1:
                return encode_exception(slave, function, ILLEGAL_DATA_ADDRESS)
            if values != [STREAM_START]:
                return encode_exception(slave, function, ILLEGAL_DATA_VALUE)
            self.streaming = True
            return encode_write_registers_reply(slave, first, 1)
        return encode_exception(frame[0], function, ILLEGAL_FUNCTION)

    def _handle_input(self, buf: bytearray) -> None:
        if self.streaming:
            if b"\xff" in buf:  # the stop sequence; the sensor ignores all else meanwhile
                self.streaming = False
                del buf[: buf.rfind(b"\xff") + 1]
            else:
                buf.clear()
                return
        while buf:
            while buf and buf[0] == 0xFF:  # tail of a stop sequence
                del buf[0]
            if len(buf) < 4:
                return
            n = modbus.request_length(buf)
            if n is None and buf[1] in (3, 4, 6, 16):
                return  # function 16 header not complete yet
            if n is None:  # unknown function: the frame ends where a CRC matches
                n = next((k for k in range(4, len(buf) + 1)
                          if crc16_modbus(bytes(buf[:k - 2])) == int.from_bytes(
                              buf[k - 2:k], "little")), None)
                if n is None:
                    if len(buf) > 256:
                        del buf[0]
                        continue
                    return
            if len(buf) < n:
                return
            frame = bytes(buf[:n])
            if crc16_modbus(frame[:-2]) != int.from_bytes(frame[-2:], "little"):
                del buf[0]  # noise or a partial frame: resynchronise
                continue
            del buf[:n]
            if frame[0] != SLAVE_ID:
                continue  # another slave's request (or a broadcast): no answer
            reply = self._answer(frame)
            if reply is not None:
                self._send(reply)
            if self.streaming:
                buf.clear()
                return

    def _frame(self) -> bytes:
        if self._last is not None and self.world.faults.active(self.device, "frozen"):
            return self._last
        self._last = encode_stream_frame(self.world.sensor_wrench(self.device))
        return self._last

    def _run(self) -> None:
        buf = bytearray()
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        dead = False
        last_rx = time.monotonic()
        while not self.stopping.is_set():
            timeout = max(0.0, next_t - time.monotonic()) if self.streaming else SILENCE
            r, _, _ = select.select([self.master], [], [], timeout)
            if r:
                try:
                    buf += os.read(self.master, 4096)
                    last_rx = time.monotonic()
                except (BlockingIOError, OSError):
                    pass
                if not dead:
                    self._handle_input(buf)
            elif buf and time.monotonic() - last_rx > SILENCE:
                buf.clear()  # end of frame: what did not make a request is dropped
            if self.fault("disconnect"):
                dead, self.streaming = True, False
            if not self.streaming:
                next_t = time.monotonic()
                continue
            if time.monotonic() < next_t:
                continue
            next_t += period
            with self.send_lock:  # a client's window opens between two frames
                frame = self._frame()
                if self.fault("drop"):
                    continue
                if self.fault("bad_crc"):
                    frame = frame[:14] + bytes([frame[14] ^ 0x5A, frame[15]])
                elif self.fault("garbage"):
                    frame = os.urandom(int(self.world.rng.integers(1, 40)))
                self._send(frame)
        os.close(self.master)
        os.close(self.slave)
