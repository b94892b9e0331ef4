"""Typed readings returned by drivers: value, unit, frame and timestamp.

All values are in SI units (m, rad, N, N m). ``timestamp`` is seconds on the
host's monotonic clock (:func:`time.monotonic`) when the reading was taken;
``wall_time`` is the POSIX time of the same instant, for the campaign record.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np


def _now() -> float:
    return time.monotonic()


def _wall() -> float:
    return time.time()


@dataclass(frozen=True)
class JointAngles:
    """Joint angles of a robot.

    Attributes
    ----------
    value : ndarray, shape (n,)
        Joint angles (rad), in the convention named by ``convention``.
    convention : str
        ``"controller"`` (teach-pendant zero and signs) or ``"model"``.
    """

    value: np.ndarray
    unit: str = "rad"
    convention: str = "controller"
    source: str = ""
    timestamp: float = field(default_factory=_now)
    wall_time: float = field(default_factory=_wall)


@dataclass(frozen=True)
class Pose:
    """A rigid pose ``T`` (4x4 homogeneous, metres) of ``child`` in ``frame``.

    Attributes
    ----------
    value : ndarray, shape (4, 4)
        Homogeneous transform; translation in m.
    sigma : ndarray or None, shape (6,)
        One standard deviation of [x, y, z (m), rx, ry, rz (rad)] when the
        instrument reports it, else None.
    residual : float or None
        RMS residual (m) of a rigid fit when the pose was computed from
        several reflectors, else None.
    """

    value: np.ndarray
    frame: str = "base"
    child: str = "tool"
    unit: str = "m"
    sigma: np.ndarray | None = None
    residual: float | None = None
    source: str = ""
    timestamp: float = field(default_factory=_now)
    wall_time: float = field(default_factory=_wall)


@dataclass(frozen=True)
class Point:
    """A measured 3-D point.

    Attributes
    ----------
    value : ndarray, shape (3,)
        Coordinates (m) in ``frame``.
    sigma : ndarray or None, shape (3,)
        One standard deviation per coordinate (m) when reported.
    """

    value: np.ndarray
    frame: str = "tracker"
    unit: str = "m"
    sigma: np.ndarray | None = None
    target: str = ""
    source: str = ""
    timestamp: float = field(default_factory=_now)
    wall_time: float = field(default_factory=_wall)


@dataclass(frozen=True)
class Wrench:
    """A force/torque measurement, averaged over a window.

    Attributes
    ----------
    value : ndarray, shape (6,)
        [fx, fy, fz (N), mx, my, mz (N m)] expressed in ``frame`` at ``point``.
    spread : ndarray, shape (6,)
        Sample standard deviation over the averaging window (same units);
        zeros for a single sample.
    samples : int
        Number of samples averaged.
    raw : ndarray, shape (samples, 6), or None
        The individual samples averaged (same units and frame), kept so that a
        campaign can store every reading.
    """

    value: np.ndarray
    frame: str = "sensor"
    point: str = "sensor origin"
    unit: str = "N, N m"
    spread: np.ndarray = field(default_factory=lambda: np.zeros(6))
    samples: int = 1
    raw: np.ndarray | None = None
    source: str = ""
    timestamp: float = field(default_factory=_now)
    wall_time: float = field(default_factory=_wall)


def average_wrench(samples: np.ndarray, **kwargs: object) -> Wrench:
    """Average raw wrench samples into a :class:`Wrench` with its spread.

    Parameters
    ----------
    samples : ndarray, shape (m, 6)
        Individual wrenches (N, N m).
    **kwargs
        Passed on to :class:`Wrench` (frame, point, source).
    """
    arr = np.asarray(samples, dtype=float).reshape(-1, 6)
    spread = arr.std(axis=0, ddof=1) if len(arr) > 1 else np.zeros(6)
    return Wrench(value=arr.mean(axis=0), spread=spread, samples=len(arr), raw=arr.copy(),
                  **kwargs)
