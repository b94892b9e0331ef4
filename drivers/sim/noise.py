"""Reproducible noise of the simulated lab: one generator per (seed, instrument, context, sample).

Several fakes serve their clients from their own threads; drawing every
sample from one generator made the numbers depend on which thread came first.
Here each draw gets its own generator, seeded by a :class:`numpy.random.SeedSequence`
whose spawn key names what is measured:

``(instrument, *context, window, sample)``

* ``instrument``: a fixed code of the noise source (``force_torque``,
  ``tracker``, ``encoders``: CRC-32 of the name);
* ``context``: what the client is doing, told by the acquisition through
  :meth:`NoiseStreams.mark` (test id, repeat, attempt and a code of the phase);
  empty until a first mark;
* ``window``: averaging windows opened in this context (:meth:`new_window`, for
  a streaming sensor whose client starts a window after dropping stale samples);
* ``sample``: draws of this instrument since the mark or the window.

So the k-th sample of a window, or the k-th pose reading of a phase, carries
the same noise whatever the threads did before it; readings a client takes a
timing-dependent number of times (settling detection) stay in their own phase.

A value a fake reads over and over at its own pace and streams (the UR fake's
joint angles, polled from the world every 5 ms) cannot be numbered by the
client's reads: :meth:`NoiseStreams.held` gives it one draw per context instead
(the same whatever the number of polls), like an encoder at standstill.
"""

from __future__ import annotations

import threading
import zlib
from collections.abc import Hashable

import numpy as np


def code(name: str) -> int:
    """Stable non-negative integer of a name (CRC-32), for spawn keys."""
    return zlib.crc32(name.encode("utf-8"))


class NoiseStreams:
    """Per-instrument counters and the seeded draws keyed by them (thread-safe).

    Parameters
    ----------
    seed : int
        The lab's seed (non-negative).
    """

    def __init__(self, seed: int) -> None:
        self.seed = int(seed)
        self.context: tuple[int, ...] = ()
        self._window: dict[str, int] = {}
        self._sample: dict[str, int] = {}
        self._lock = threading.Lock()

    def mark(self, *context: Hashable) -> None:
        """Start a new context (e.g. test id, repeat, attempt, phase); counters restart."""
        key = tuple(code(c) if isinstance(c, str) else int(c) for c in context)
        with self._lock:
            self.context = key
            self._window.clear()
            self._sample.clear()

    def new_window(self, instrument: str) -> None:
        """The client of ``instrument`` opens an averaging window: samples restart at 0."""
        with self._lock:
            self._window[instrument] = self._window.get(instrument, 0) + 1
            self._sample[instrument] = 0

    def key(self, instrument: str) -> tuple[int, ...]:
        """Spawn key of the next draw of ``instrument`` (and count it)."""
        with self._lock:
            n = self._sample.get(instrument, 0)
            self._sample[instrument] = n + 1
            return (code(instrument), *self.context, self._window.get(instrument, 0), n)

    def generator(self, instrument: str) -> np.random.Generator:
        """A generator for the next sample of ``instrument``."""
        seq = np.random.SeedSequence(self.seed, spawn_key=self.key(instrument))
        return np.random.Generator(np.random.PCG64(seq))

    def held(self, instrument: str) -> np.random.Generator:
        """A generator of the one draw of ``instrument`` held through the current
        context (not counted: every call in the context gives the same numbers)."""
        with self._lock:
            key = (code(f"{instrument}/held"), *self.context)
        return np.random.Generator(np.random.PCG64(np.random.SeedSequence(self.seed,
                                                                          spawn_key=key)))
