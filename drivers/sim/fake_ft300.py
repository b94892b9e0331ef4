"""Fake Robotiq FT 300 on a pseudo-terminal: Modbus RTU start, 100 Hz stream, 0xFF stop."""

from __future__ import annotations

import os
import select
import time
import tty

from drivers.errors import ProtocolError
from drivers.modbus import decode_write_registers_request, encode_write_registers_reply
from drivers.robotiq_ft300 import SLAVE_ID, STREAM_REGISTER, STREAM_START, encode_stream_frame
from drivers.sim.base import FakeServer
from drivers.sim.world import World


class FakeFT300(FakeServer):
    """Serves the FT 300 protocol on the master side of a pty; the driver opens the slave."""

    driver = "robotiq-ft300"
    device = "robotiq-ft300"

    def __init__(self, world: World, rate_hz: float = 100.0) -> None:
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

    def _handle_input(self, buf: bytearray) -> None:
        if b"\xff" in buf:
            self.streaming = False
            del buf[: buf.rfind(b"\xff") + 1]
            return
        while len(buf) >= 11:
            idx = buf.find(bytes([SLAVE_ID, 0x10]))
            if idx < 0:
                buf.clear()
                return
            del buf[:idx]
            if len(buf) < 11:
                return
            try:
                slave, first, values = decode_write_registers_request(bytes(buf[:11]))
            except ProtocolError:
                del buf[:1]
                continue
            del buf[:11]
            if first == STREAM_REGISTER and values == [STREAM_START]:
                self._send(encode_write_registers_reply(slave, first, 1))
                self.streaming = True

    def _frame(self) -> bytes:
        if self._last is not None and self.world.faults.active(self.device, "frozen"):
            return self._last
        self._last = encode_stream_frame(self.world.sensor_wrench())
        return self._last

    def _run(self) -> None:
        buf = bytearray()
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        dead = False
        while not self.stopping.is_set():
            timeout = max(0.0, next_t - time.monotonic()) if self.streaming else 0.05
            r, _, _ = select.select([self.master], [], [], timeout)
            if r:
                try:
                    buf += os.read(self.master, 4096)
                except (BlockingIOError, OSError):
                    pass
                if not dead:
                    self._handle_input(buf)
            if self.fault("disconnect"):
                dead, self.streaming = True, False
            if not self.streaming:
                next_t = time.monotonic()
                continue
            if time.monotonic() < next_t:
                continue
            next_t += period
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
