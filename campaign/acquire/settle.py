"""Settling detection from tracker readings (no fixed sleep).

The tool point is read every ``interval`` seconds; the robot is taken as
settled when the mean of the newer half of the last ``window`` readings
differs from the mean of the older half by less than ``tolerance``. For an
exponential settling this bounds the motion left after the window to a few
per cent of the tolerance once the window spans about four time constants;
the tolerance is set from the tracker noise so that noise alone rarely keeps
the test waiting.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from drivers.errors import DeviceTimeout


@dataclass(frozen=True)
class SettleRule:
    """When a series of point readings counts as settled.

    Attributes
    ----------
    interval : float
        Wall-clock time between readings (s).
    window : int
        Number of readings compared (even, >= 4).
    tolerance : float
        Largest accepted distance between the means of the two halves (m).
    timeout : float
        Wall-clock time after which settling has failed (s).
    """

    interval: float
    window: int
    tolerance: float
    timeout: float

    def __post_init__(self) -> None:
        if self.window < 4 or self.window % 2:
            raise ValueError("settle window must be an even number >= 4")
        if not (self.interval >= 0 and self.tolerance > 0 and self.timeout > 0):
            raise ValueError("settle interval, tolerance and timeout must be positive")


def rule_for(noise: float, time_scale: float = 1.0, settle_scale: float = 0.5,
             window: int = 10) -> SettleRule:
    """Rule from the tracker noise and the expected settling time.

    Parameters
    ----------
    noise : float
        Standard deviation of one coordinate of a point reading (m).
    time_scale : float
        Simulated time runs this many times faster than the wall clock (1 on hardware).
    settle_scale : float
        Expected settling time constant (s of robot time); the window spans
        about four of them.
    window : int
        Readings compared.
    """
    interval = 4 * settle_scale / (window / 2) / time_scale
    half_mean_sigma = noise * np.sqrt(2.0 / (window / 2)) * np.sqrt(3.0)
    tolerance = max(4.0 * half_mean_sigma, 2e-6)
    # at least 10 s of wall clock: a loaded machine must not turn into a settling failure
    timeout = max(60.0 * settle_scale / time_scale, 20 * interval * window, 10.0)
    return SettleRule(interval=interval, window=window, tolerance=tolerance, timeout=timeout)


def half_difference(points: np.ndarray) -> float:
    """Distance (m) between the means of the older and newer halves of ``points`` (k, 3)."""
    p = np.asarray(points, dtype=float)
    h = len(p) // 2
    return float(np.linalg.norm(p[-h:].mean(axis=0) - p[-2 * h:-h].mean(axis=0)))


def wait_settled(read: Callable[[], np.ndarray], rule: SettleRule,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> tuple[np.ndarray, int]:
    """Read points until they settle; returns (last window of points (m), readings taken).

    Raises
    ------
    DeviceTimeout
        If the readings have not settled after ``rule.timeout`` seconds.
    """
    start = clock()
    points: list[np.ndarray] = []
    while True:
        points.append(np.asarray(read(), dtype=float))
        if len(points) >= rule.window and \
                half_difference(points[-rule.window:]) < rule.tolerance:
            return np.array(points[-rule.window:]), len(points)
        if clock() - start > rule.timeout:
            moved = half_difference(points[-rule.window:]) if len(points) >= rule.window \
                else float("nan")
            raise DeviceTimeout(f"tool still moving after {rule.timeout:.1f} s "
                                f"({moved * 1e6:.0f} um between half-windows)")
        sleep(rule.interval)
