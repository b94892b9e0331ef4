"""Common scaffolding of the fake instruments: a named background thread with a stop flag."""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from collections.abc import Iterator
from contextlib import contextmanager

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
        #: held while a streaming fake makes and sends one sample
        self.send_lock = threading.Lock()

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

    @contextmanager
    def window(self) -> Iterator[None]:
        """A client's averaging window opens: no sample is sent while the client drops
        what is buffered, and the samples after it are numbered from 0 again
        (:meth:`drivers.sim.noise.NoiseStreams.new_window`)."""
        with self.send_lock:
            yield
            self.world.noise_streams.new_window(self.device)

    def fault(self, name: str) -> bool:
        """Consume one occurrence of fault ``name`` armed on this device."""
        return self.world.faults.take(self.device, name)
