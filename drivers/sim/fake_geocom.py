"""Fake GeoCOM instrument over TCP or a serial pty (ASCII protocol, *TPS1200 GeoCOM Reference
Manual* section 2): requests ``[<LF>]%R1Q,<RPC>[,<TrId>]:<params>`` each on one line; an
empty line (the LF a client sends to clear the line) is ignored. RPCs: COM_NullProc (0),
CSV_GetInstrumentNo (5003), CSV_GetInstrumentName (5004), TMC_DoMeasure (2008),
TMC_GetCoordinate (2082); others get return code 1.
"""

from __future__ import annotations

import os
import select
import socket
import threading
import tty
from collections.abc import Callable

from drivers.errors import ProtocolError
from drivers.geocom import RPC_DO_MEASURE, RPC_GET_COORDINATE, decode_request, encode_reply
from drivers.sim.base import FakeServer
from drivers.sim.tcp import TcpFake
from drivers.sim.world import World

RPC_NULL_PROC = 0  # COM_NullProc: "%R1Q,0:" -> "%R1P,0,0:0"
RPC_INSTRUMENT_NO = 5003  # CSV_GetInstrumentNo -> serial number (long)
RPC_INSTRUMENT_NAME = 5004  # CSV_GetInstrumentName -> name (string)
INSTRUMENT_NO = 123456
INSTRUMENT_NAME = "SIM GEOCOM"
RC_ANGLE_ONLY = 1285  # TMC_ANGLE_OK: no distance, as when the beam is lost
RC_UNKNOWN_RPC = 1  # GRC_IVRESULT is close enough for an RPC the fake does not know
LATE_DELAY = 1.5  # s, how late a "late" reply comes


def respond(fake: FakeServer, line: bytes, send: Callable[[bytes], None]) -> bool:
    """Answer one request line through ``send``; False means "hang up" (disconnect fault)."""
    world = fake.world
    if not line.strip():
        return True  # an empty line (a client clearing the line): ignored, as instruments do
    try:
        rpc, _params, trid = decode_request(line)
    except ProtocolError:
        send(b"%R1P,1,0:\r\n")  # communication error reply
        return True
    if fake.fault("disconnect"):
        return False
    if fake.fault("drop"):
        return True
    if fake.fault("garbage"):
        send(os.urandom(int(world.rng.integers(1, 60))) + b"\r\n")
        return True
    if rpc == RPC_NULL_PROC:
        send(encode_reply(0, trid=trid))
    elif rpc == RPC_INSTRUMENT_NO:
        send(encode_reply(0, INSTRUMENT_NO, trid=trid))
    elif rpc == RPC_INSTRUMENT_NAME:
        send(encode_reply(0, f'"{INSTRUMENT_NAME}"', trid=trid))
    elif rpc == RPC_DO_MEASURE:
        send(encode_reply(0, trid=trid))
    elif rpc == RPC_GET_COORDINATE:
        if fake.fault("beam_lost"):
            send(encode_reply(RC_ANGLE_ONLY, 0, 0, 0, 0, 0, 0, 0, 0, trid=trid))
            return True
        e, n, h = world.tracker_point(source=fake.device)
        reply = encode_reply(0, f"{e:.7f}", f"{n:.7f}", f"{h:.7f}", 0,
                             f"{e:.7f}", f"{n:.7f}", f"{h:.7f}", 0, trid=trid)
        if fake.fault("late"):
            timer = threading.Timer(LATE_DELAY, send, args=(reply,))
            timer.daemon = True
            timer.start()
        else:
            send(reply)
    else:
        send(encode_reply(RC_UNKNOWN_RPC, trid=trid))
    return True


class FakeGeoCom(TcpFake):
    """GeoCOM over loopback TCP, serving the aimed reflector's coordinates (m)."""

    driver = "geocom"
    device = "geocom"

    def __init__(self, world: World, port: int = 0) -> None:
        super().__init__(world, port=port)
        self.url = f"socket://{self.host}:{self.port}"

    def serve(self, conn: socket.socket) -> None:
        def send(data: bytes) -> None:
            try:
                conn.sendall(data)
            except OSError:
                pass

        while True:
            line = self.recv_line(conn)
            if line is None or not respond(self, line, send):
                return


class FakeGeoComSerial(FakeServer):
    """GeoCOM on the master side of a pseudo-terminal; the driver opens the slave path."""

    driver = "geocom"
    device = "geocom"

    def __init__(self, world: World) -> None:
        super().__init__(world)
        self.master, self.slave = os.openpty()
        tty.setraw(self.master)
        tty.setraw(self.slave)
        self.url = f"{os.ttyname(self.slave)}?baud=19200"

    def _send(self, data: bytes) -> None:
        try:
            os.write(self.master, data)
        except OSError:
            pass

    def _run(self) -> None:
        buf = bytearray()
        dead = False
        while not self.stopping.is_set():
            ready, _, _ = select.select([self.master], [], [], 0.05)
            if not ready:
                continue
            try:
                buf += os.read(self.master, 1024)
            except OSError:
                continue
            while b"\n" in buf and not dead:
                line, _, rest = bytes(buf).partition(b"\n")
                buf = bytearray(rest)
                dead = not respond(self, line + b"\n", self._send)
            if dead:
                buf.clear()
        os.close(self.master)
        os.close(self.slave)
