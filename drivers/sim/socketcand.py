"""A CAN bus on loopback: a socketcand server (TCP, ASCII) with one simulated node on it.

socketcand (github.com/linux-can/socketcand, ``doc/protocol.md``) exposes a
CAN bus over one TCP connection per client. The subset served here is what a
raw-mode client needs, and it is the whole of what python-can's ``socketcand``
interface speaks:

* on connect the server sends ``< hi >``;
* ``< open BUS >`` -> ``< ok >`` for the served bus name, else ``< error ... >``;
* ``< rawmode >`` -> ``< ok >`` (after an ``open``); ``< echo >`` -> ``< echo >``;
* in raw mode ``< send ID DLC B0 B1 ... >`` (ID 3 hex digits for 11-bit, 8 for
  29-bit identifiers; DLC and bytes in hex) puts a frame on the bus, and every
  frame of the bus sent by another node reaches the client as
  ``< frame ID SECONDS.MICROSECONDS DATA >`` (data as contiguous two-digit hex,
  empty for a frame without data).

As on a CAN bus, a frame reaches every node but its sender: the simulated node
(:attr:`CanHub.node`) and every other raw-mode client. The server listens on
127.0.0.1 only, so nothing leaves the host. Not served: the broadcast beacon on
UDP 42000 (clients are given the address), BCM mode, control mode and
``isotpmode``, CAN FD, remote and error frames.
"""

from __future__ import annotations

import re
import socket
import threading
import time
from collections.abc import Callable

#: the simulated node's handler: (arbitration id, extended, data) -> frames to send back
Node = Callable[[int, bool, bytes], list[tuple[int, bytes]]]

_SEND = re.compile(r"^<\s*send\s+([0-9A-Fa-f]{1,8})\s+([0-9A-Fa-f])\s*((?:[0-9A-Fa-f]{1,2}\s*)*)>$")


def frame_text(arbitration_id: int, data: bytes, extended: bool = False,
               stamp: float | None = None) -> str:
    """The ``< frame ... >`` line socketcand sends for one received frame."""
    t = time.time() if stamp is None else stamp
    ident = f"{arbitration_id:08X}" if extended else f"{arbitration_id & 0x7FF:03X}"
    return f"< frame {ident} {int(t)}.{int((t % 1) * 1e6):06d} {data.hex().upper()} >"


def parse_send(text: str) -> tuple[int, bool, bytes] | None:
    """``(id, extended, data)`` of a ``< send ... >`` command, or None when malformed."""
    m = _SEND.match(text.strip())
    if m is None:
        return None
    ident, dlc = m.group(1), int(m.group(2), 16)
    data = bytes(int(b, 16) for b in m.group(3).split())
    if dlc > 8 or len(data) != dlc:
        return None
    extended = len(ident) > 3
    arbitration_id = int(ident, 16)
    if arbitration_id > (0x1FFFFFFF if extended else 0x7FF):
        return None
    return arbitration_id, extended, data


class _Client:
    """One TCP client of the hub and its protocol state."""

    def __init__(self, conn: socket.socket) -> None:
        self.conn = conn
        self.raw = False
        self.opened = False
        self.lock = threading.Lock()

    def write(self, text: str) -> bool:
        try:
            with self.lock:
                self.conn.sendall(text.encode("ascii"))
            return True
        except OSError:
            return False


class CanHub:
    """socketcand server on 127.0.0.1 for one bus, with one simulated node attached.

    Parameters
    ----------
    bus : str
        Bus name clients open (``< open BUS >``).
    node : callable
        The simulated device: called for every frame a client sends, returns the
        frames (id, data) it puts on the bus in answer (11-bit identifiers).
    """

    def __init__(self, bus: str, node: Node) -> None:
        self.bus = bus
        self.node = node
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(8)
        self.host, self.port = self.sock.getsockname()[:2]
        self.clients: list[_Client] = []
        self._lock = threading.Lock()
        self.stopping = threading.Event()

    def serve(self) -> None:
        """Accept clients until :meth:`close` (run in a thread)."""
        self.sock.settimeout(0.2)
        while not self.stopping.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            except OSError:
                break
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            client = _Client(conn)
            with self._lock:
                self.clients.append(client)
            threading.Thread(target=self._serve_client, args=(client,), daemon=True,
                             name="fake-socketcand-client").start()

    def close(self) -> None:
        self.stopping.set()
        try:
            self.sock.close()
        except OSError:
            pass
        with self._lock:
            clients, self.clients = self.clients, []
        for c in clients:
            try:
                c.conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            c.conn.close()

    def broadcast(self, arbitration_id: int, data: bytes, sender: _Client | None = None,
                  extended: bool = False) -> None:
        """Put a frame on the bus: every raw-mode client but ``sender`` receives it."""
        text = frame_text(arbitration_id, data, extended)
        with self._lock:
            targets = [c for c in self.clients if c.raw and c is not sender]
        for c in targets:
            c.write(text)

    def _serve_client(self, client: _Client) -> None:
        client.write("< hi >")
        buf = ""
        client.conn.settimeout(0.2)
        while not self.stopping.is_set():
            try:
                chunk = client.conn.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                break
            if not chunk:
                break
            buf += chunk.decode("ascii", errors="replace")
            while True:
                start, end = buf.find("<"), buf.find(">")
                if start < 0:
                    buf = ""
                    break
                if end < 0:
                    buf = buf[start:] if len(buf) - start <= 200 else ""
                    break
                if end < start:
                    buf = buf[start:]
                    continue
                self._command(client, buf[start:end + 1])
                buf = buf[end + 1:]
        with self._lock:
            if client in self.clients:
                self.clients.remove(client)
        client.conn.close()

    def _command(self, client: _Client, text: str) -> None:
        words = text[1:-1].split()
        if not words:
            client.write("< error empty command >")
            return
        cmd = words[0]
        if cmd == "echo":
            client.write("< echo >")
        elif cmd == "open":
            if len(words) == 2 and words[1] == self.bus:
                client.opened = True
                client.write("< ok >")
            else:
                client.write("< error could not open bus >")
        elif cmd == "rawmode" and client.opened:
            client.raw = True
            client.write("< ok >")
        elif cmd == "send" and client.raw:
            frame = parse_send(text)
            if frame is None:
                client.write("< error malformed send >")
                return
            arbitration_id, extended, data = frame
            self.broadcast(arbitration_id, data, sender=client, extended=extended)
            for reply_id, reply in self.node(arbitration_id, extended, data):
                self.broadcast(reply_id, reply)
        else:
            client.write("< error unknown command >")
