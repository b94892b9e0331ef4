"""A blocking TCP link with timeouts, for drivers that exchange framed messages.

Mixed into a role class before it (``class X(TcpLink, RobotController)``): it
provides the role's ``_connect``/``_close`` hooks and ``_recv_exact``, mapping
socket errors onto the driver exception tree.
"""

from __future__ import annotations

import socket

from drivers.errors import ConnectionFailed, DeviceTimeout


class TcpLink:
    """TCP connection to ``self.host:self.port`` with ``self.timeout`` (s) on every call.

    Subclasses set ``peer`` (a name for messages) and ``host``, ``port``,
    ``timeout``, ``address`` (from the role base).
    """

    peer = "device"
    host: str
    port: int
    timeout: float
    address: str
    _sock: socket.socket | None = None

    def _connect(self) -> None:
        try:
            self._sock = socket.create_connection((self.host, self.port), timeout=self.timeout)
        except TimeoutError as err:
            raise DeviceTimeout(f"{self.address}: connect timed out") from err
        except OSError as err:
            raise ConnectionFailed(f"{self.address}: {err}") from err

    def _close(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _recv_exact(self, n: int) -> bytes:
        """Exactly ``n`` bytes, or DeviceTimeout/ConnectionFailed."""
        if self._sock is None:
            raise ConnectionFailed(f"{self.address}: not connected")
        buf = bytearray()
        while len(buf) < n:
            try:
                chunk = self._sock.recv(n - len(buf))
            except TimeoutError as err:
                raise DeviceTimeout(f"{self.address}: no reply within {self.timeout} s") from err
            except OSError as err:
                raise ConnectionFailed(f"{self.address}: {err}") from err
            if not chunk:
                raise ConnectionFailed(f"{self.address}: {self.peer} closed the connection")
            buf += chunk
        return bytes(buf)
