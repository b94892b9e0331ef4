"""Time stamps of a run's readings: the UTC wall clock on hardware, the lab's clock on --fake.

On a robot, ``t_utc`` of ``tests.csv`` and ``samples.jsonl`` is the wall clock
(:class:`WallClock`), as always. On the simulated lab it is the lab's own clock
(:class:`SimulatedClock`): it reads :data:`SIM_EPOCH_UTC` when the robot reaches the
first test's approach pose and advances by simulated durations only, never by the
wall clock, so a seeded fake run writes the same time stamps whatever the machine's
load, the time scale or a ``kill -9`` and ``--resume`` in between:

* a motion: :func:`campaign.acquire.preflight.move_time` of its largest joint step
  (controller rad) at the protocol's speed and acceleration; the first motion of a
  run (to the first approach pose, from wherever the robot stood) counts 0;
* a settling phase: the lab's settling (:data:`drivers.sim.world.SETTLED_AFTER` time
  constants ``settle_time``, after which its state is the equilibrium) plus one
  detection window of readings ((window - 1) x interval), whatever the number of
  readings the detection took on the wall clock; the k-th reading of it is stamped
  k intervals after its start (the last ones at its end if there were more);
* a window of F/T samples: samples / the driver's nominal rate;
* a tracker reading, a load change, a tare's bookkeeping: no time.

The clock is held in whole microseconds (the resolution of the stamps), so a resumed
session that restarts it from the last row of ``tests.csv`` continues exactly where
an uninterrupted run would be. The session's wall-clock times stay in
``metadata.json`` (``started_utc``, ``ended_utc``, ``sessions``) and ``events.jsonl``;
``metadata.json`` ``time_stamps`` says which clock a run's ``t_utc`` follows.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from datetime import UTC, datetime, timedelta

import numpy as np

#: the simulated lab's clock reads this when the first approach motion of a run ends
SIM_EPOCH_UTC = "2000-01-01T00:00:00.000000+00:00"
_EPOCH = datetime.fromisoformat(SIM_EPOCH_UTC)


def utc(wall: float | None = None) -> str:
    """ISO 8601 UTC time stamp with microseconds (``wall``: POSIX s, default now)."""
    t = time.time() if wall is None else wall
    return datetime.fromtimestamp(t, UTC).isoformat(timespec="microseconds")


def describe(simulated: bool) -> dict[str, str]:
    """The ``time_stamps`` record of ``metadata.json`` for a run on the lab or on hardware."""
    if not simulated:
        return {"clock": "utc", "text": "t_utc of tests.csv and samples.jsonl: UTC wall clock"}
    return {"clock": "simulated", "epoch_utc": SIM_EPOCH_UTC,
            "text": "t_utc of tests.csv and samples.jsonl: SIMULATED lab clock from "
                    f"{SIM_EPOCH_UTC[:19]}Z (motion, settling and sampling durations only, "
                    "not the wall clock); the wall clock is in started_utc, ended_utc, "
                    "sessions and events.jsonl"}


class WallClock:
    """Stamps of a run on hardware: the UTC wall clock, or the reading's own time."""

    simulated = False

    def stamp(self, wall: float | None = None) -> str:
        """Stamp of a reading taken at POSIX time ``wall`` (default: now)."""
        return utc(wall)

    def resume(self, last_stamp: str | None, q_last: np.ndarray | None) -> None:
        """Nothing to restore: the wall clock goes on by itself."""

    def move(self, q_ctrl: np.ndarray) -> None:
        """A motion to ``q_ctrl``: the wall clock goes on by itself."""

    def wait(self, seconds: float) -> None:
        """A window of ``seconds``: the wall clock goes on by itself."""

    def settle_start(self) -> None:
        """A settling phase starts."""

    def settle_read(self) -> None:
        """A settling reading is taken."""

    def settle_end(self) -> None:
        """The settling phase is over."""


class SimulatedClock(WallClock):
    """The simulated lab's clock (see the module docstring), in whole microseconds.

    Parameters
    ----------
    speed, acceleration : float
        The motions' joint speed (rad/s) and acceleration (rad/s^2).
    settle_s : float
        Simulated duration of one settling phase (s).
    interval_s : float
        Simulated time between two settling readings (s).
    """

    simulated = True

    def __init__(self, speed: float, acceleration: float, settle_s: float,
                 interval_s: float) -> None:
        if not (speed > 0 and acceleration > 0 and settle_s >= 0 and interval_s >= 0):
            raise ValueError("speed and acceleration must be positive, durations >= 0")
        self.speed, self.acceleration = speed, acceleration
        self.settle_us, self.interval_us = _us(settle_s), _us(interval_s)
        self.now_us = 0  # after SIM_EPOCH_UTC
        self.q_last: np.ndarray | None = None
        self._settle_from = 0
        self._reads = 0

    def stamp(self, wall: float | None = None) -> str:
        """The clock's time; the reading's wall-clock time is not used."""
        return (_EPOCH + timedelta(microseconds=self.now_us)).isoformat(timespec="microseconds")

    def resume(self, last_stamp: str | None, q_last: Sequence[float] | None) -> None:
        """Continue after the last row of ``tests.csv``: its stamp and its test's pose
        (controller rad); a run without rows starts again at the epoch."""
        if last_stamp is None:
            self.now_us, self.q_last = 0, None
            return
        # whole microseconds, exactly (total_seconds() would go through a float)
        delta = datetime.fromisoformat(last_stamp) - _EPOCH
        self.now_us = (delta.days * 86400 + delta.seconds) * 1_000_000 + delta.microseconds
        self.q_last = None if q_last is None else np.asarray(q_last, dtype=float).copy()

    def move(self, q_ctrl: np.ndarray) -> None:
        """A motion to ``q_ctrl`` (controller rad) from the last target."""
        from campaign.acquire.preflight import move_time

        q = np.asarray(q_ctrl, dtype=float)
        if self.q_last is not None:
            step = float(np.max(np.abs(q - self.q_last)))
            self.now_us += _us(float(move_time(step, self.speed, self.acceleration)))
        self.q_last = q.copy()

    def wait(self, seconds: float) -> None:
        """A sampling window of ``seconds`` (simulated)."""
        self.now_us += _us(seconds)

    def settle_start(self) -> None:
        self._settle_from, self._reads = self.now_us, 0

    def settle_read(self) -> None:
        """The k-th reading (k = 0, 1, ...) sits k intervals after the start, at most at
        the end of the phase."""
        self.now_us = self._settle_from + min(self._reads * self.interval_us, self.settle_us)
        self._reads += 1

    def settle_end(self) -> None:
        self.now_us = self._settle_from + self.settle_us


def _us(seconds: float) -> int:
    return round(float(seconds) * 1e6)
