"""A small threaded TCP server base for fakes: one handler call per connection."""

from __future__ import annotations

import socket
from abc import abstractmethod
from collections.abc import Callable

from drivers.sim.base import FakeServer
from drivers.sim.world import World


def serve_then_close(serve: Callable[[socket.socket], None], conn: socket.socket) -> None:
    """Run ``serve(conn)``; a client that resets or vanishes (OSError) ends it quietly."""
    try:
        serve(conn)
    except OSError:
        pass
    finally:
        conn.close()


class TcpFake(FakeServer):
    """Listens on 127.0.0.1 (``port=0``: any free port) and serves each client in a thread."""

    def __init__(self, world: World, host: str = "127.0.0.1", port: int = 0) -> None:
        super().__init__(world)
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind((host, port))
        self.listener.listen(8)
        self.listener.settimeout(0.1)
        self.host, self.port = self.listener.getsockname()[:2]
        self._clients: list[socket.socket] = []

    def _run(self) -> None:
        while not self.stopping.is_set():
            try:
                conn, _ = self.listener.accept()
            except (TimeoutError, BlockingIOError):
                continue
            except OSError:
                break
            conn.settimeout(0.2)
            # answers go out in several small writes (acknowledgement, then result): without
            # TCP_NODELAY, Nagle's algorithm and the client's delayed ACK add 40 ms to each
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._clients.append(conn)
            self._spawn(lambda c=conn: serve_then_close(self.serve, c), "client")
        self.listener.close()

    def recv_exact(self, conn: socket.socket, n: int) -> bytes | None:
        """Read ``n`` bytes, or None when the peer closed or the lab stops."""
        buf = bytearray()
        while len(buf) < n:
            if self.stopping.is_set():
                return None
            try:
                chunk = conn.recv(n - len(buf))
            except TimeoutError:
                continue
            if not chunk:
                return None
            buf += chunk
        return bytes(buf)

    def recv_line(self, conn: socket.socket, limit: int = 4096) -> bytes | None:
        """Read up to and including LF, or None when the peer closed or the lab stops."""
        buf = bytearray()
        while not buf.endswith(b"\n"):
            got = self.recv_exact(conn, 1)
            if got is None:
                return None
            buf += got
            if len(buf) > limit:
                return bytes(buf)
        return bytes(buf)

    @abstractmethod
    def serve(self, conn: socket.socket) -> None:
        """Handle one client connection until it closes."""

    def _close(self) -> None:
        for c in self._clients:
            try:
                c.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
