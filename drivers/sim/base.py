"""Common scaffolding of the fake instruments: a named background thread with a stop flag."""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod

from drivers.sim.world import World


class FakeServer(ABC):
    """A fake instrument served from background threads of the lab process.

    Subclasses set :attr:`url` in ``__init__`` (the address a real driver
    connects to) and implement :meth:`_run`, which must return soon after
    :attr:`stopping` is set.
    """

    #: registry name of the driver that talks to this fake
    driver: str = ""
    #: device name used for fault injection
    device: str = ""

    def __init__(self, world: World) -> None:
        self.world = world
        self.url = ""
        self.stopping = threading.Event()
        self._threads: list[threading.Thread] = []

    def _spawn(self, target, name: str) -> None:
        t = threading.Thread(target=target, daemon=True, name=f"fake-{self.driver}-{name}")
        self._threads.append(t)
        t.start()

    def start(self) -> None:
        self._spawn(self._run, "main")

    @abstractmethod
    def _run(self) -> None:
        """Serve until ``stopping`` is set (the server's main loop)."""

    def stop(self) -> None:
        self.stopping.set()
        self._close()
        for t in self._threads:
            t.join(timeout=2.0)

    def _close(self) -> None:  # noqa: B027 - optional hook, nothing to release by default
        """Release sockets/fds (called from :meth:`stop`)."""

    def fault(self, name: str) -> bool:
        """Consume one occurrence of fault ``name`` armed on this device."""
        return self.world.faults.take(self.device, name)
