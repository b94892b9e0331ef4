"""Fake ATI Net F/T: RDT over UDP plus ``netftapi2.xml`` over HTTP, on loopback."""

from __future__ import annotations

import http.server
import os
import socket
import time

import numpy as np

from drivers.ati_netft import (
    CMD_SET_BIAS,
    CMD_START_REALTIME,
    CMD_STOP,
    RdtRecord,
    decode_request,
    encode_record,
)
from drivers.errors import ProtocolError
from drivers.sim.base import FakeServer
from drivers.sim.world import World

CAL_XML = """<?xml version="1.0" encoding="utf-8"?>
<netft>
<prodname>Simulated Net F/T</prodname>
<setserial>SIM-0001</setserial>
<cfgcpf>{cpf}</cfgcpf>
<cfgcpt>{cpt}</cfgcpt>
<scfgfu>N</scfgfu>
<scfgtu>Nm</scfgtu>
<comrdtrate>{rate}</comrdtrate>
</netft>
"""


class FakeNetFT(FakeServer):
    """RDT streamer fed by the world's sensor wrench, with its calibration page."""

    driver = "ati-netft"
    device = "ati-netft"

    def __init__(self, world: World, rate_hz: float = 500.0, cpf: int = 100_000,
                 cpt: int = 100_000) -> None:
        super().__init__(world)
        self.rate_hz, self.cpf, self.cpt = rate_hz, cpf, cpt
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.05)
        xml = CAL_XML.format(cpf=cpf, cpt=cpt, rate=int(rate_hz)).encode()

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802 (http.server API)
                if self.path.split("?")[0] == "/netftapi2.xml":
                    self.send_response(200)
                    self.send_header("Content-Type", "text/xml")
                    self.send_header("Content-Length", str(len(xml)))
                    self.end_headers()
                    self.wfile.write(xml)
                else:
                    self.send_error(404)

            def log_message(self, *args: object) -> None:
                pass

        self.http = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.url = (f"udp://127.0.0.1:{self.sock.getsockname()[1]}"
                    f"?http_port={self.http.server_address[1]}")
        self._peer = None
        self._seq = 0
        self._ft_seq = 0
        self._bias = np.zeros(6)
        self._last_counts: tuple[int, ...] | None = None
        self._old: bytes | None = None

    def start(self) -> None:
        super().start()
        self._spawn(self.http.serve_forever, "http")

    def _close(self) -> None:
        self.http.shutdown()
        self.http.server_close()

    def _handle_request(self, data: bytes, peer) -> None:
        try:
            cmd, _count = decode_request(data)
        except ProtocolError:
            return  # the real sensor ignores malformed requests
        if cmd == CMD_START_REALTIME:
            self._peer = peer
        elif cmd == CMD_STOP:
            self._peer = None
        elif cmd == CMD_SET_BIAS:
            self._bias = self.world.sensor_wrench(self.device)

    def _record(self) -> bytes:
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        self._ft_seq += 1
        if self._last_counts is not None and self.world.faults.active(self.device, "frozen"):
            counts = self._last_counts
        else:
            w = self.world.sensor_wrench(self.device) - self._bias
            scale = np.array([self.cpf] * 3 + [self.cpt] * 3, float)
            counts = tuple(int(v) for v in np.clip(np.round(w * scale), -2**31, 2**31 - 1))
        self._last_counts = counts
        return encode_record(RdtRecord(self._seq, self._ft_seq, 0, counts))

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        next_t = time.monotonic()
        dead = False
        while not self.stopping.is_set():
            wait = 0.05 if self._peer is None else max(0.0, min(0.01, next_t - time.monotonic()))
            self.sock.settimeout(wait if wait > 0 else 1e-4)
            try:
                data, peer = self.sock.recvfrom(64)
                if not dead:
                    self._handle_request(data, peer)
            except (TimeoutError, BlockingIOError):
                pass
            except OSError:
                break
            if self.fault("disconnect"):
                dead = True
                self._peer = None
            if self._peer is None:
                next_t = time.monotonic()
                continue
            now = time.monotonic()
            while now >= next_t and self._peer is not None:
                next_t += period
                with self.send_lock:  # a client's window opens between two records
                    self._send_record()
            if next_t < now - 1.0:
                next_t = now
        self.sock.close()

    def _send_record(self) -> None:
        """Make the next record and send it (or what a fault makes of it)."""
        pkt = self._record()
        if self.fault("drop"):
            return
        if self.fault("garbage"):
            size = int(self.world.rng.integers(1, 80))
            pkt = os.urandom(size + (size % 36 == 0))  # never record-sized
        elif self.fault("late") and self._old is not None:
            self.sock.sendto(pkt, self._peer)
            pkt = self._old
        self._old = pkt if len(pkt) == 36 else self._old
        try:
            self.sock.sendto(pkt, self._peer)
        except OSError:
            self._peer = None
