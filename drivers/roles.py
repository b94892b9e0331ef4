"""Abstract device roles: robot controller, force/torque sensor, pose tracker, load applicator.

Public methods validate arguments and enforce timeouts; subclasses implement
the small private methods (``_connect``, ``_read_sample``, ...) that talk to
the wire. Every role has ``describe()`` returning the units and frames of what
it produces, for the campaign's metadata file.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import DeviceFault, DeviceTimeout, DriverError
from drivers.loopback_guard import check_address
from drivers.readings import JointAngles, Point, Pose, Wrench, average_wrench


def address_timeout(address: str, default: float) -> float:
    """The deadline (s) an address states with ``?timeout=S`` (any scheme), else
    ``default``: the simulated lab states a longer one for its streaming sensors (a
    simulation starved of CPU is not a device fault) while real devices keep the
    drivers' own."""
    if "?" not in address:  # no options: nothing to parse (and "" is no address)
        return default
    return parse_address(address).float_option("timeout", default)


class Driver(ABC):
    """Common part of every driver: an address, connect/close, describe, context manager."""

    #: role name used in ``describe()`` and the registry
    role: str = "device"

    def __init__(self, address: str = "", *, timeout: float = 2.0) -> None:
        timeout = address_timeout(address, timeout)
        if timeout <= 0:
            raise ValueError(f"timeout must be positive, got {timeout}")
        self.address = address
        self.timeout = float(timeout)
        self.connected = False

    def connect(self) -> None:
        """Open the link to the device (idempotent)."""
        if not self.connected:
            check_address(self.address)
            self._connect()
            self.connected = True

    def close(self) -> None:
        """Close the link; safe to call twice."""
        if self.connected:
            self.connected = False
            self._close()

    def __enter__(self):
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @abstractmethod
    def _connect(self) -> None: ...

    @abstractmethod
    def _close(self) -> None: ...

    def describe(self) -> dict[str, Any]:
        """Units, frames and address of this device, as a plain dict."""
        return {"role": self.role, "driver": type(self).__name__, "address": self.address}


class RobotController(Driver):
    """A robot controller: joint angles in, joint angles out.

    Joint angles are in rad in the *controller* convention (teach-pendant zero
    and signs); the analysis side converts with ``RobotModel.from_controller``.
    """

    role = "robot"
    n_joints: int = 6

    def read_joints(self) -> JointAngles:
        """Return the measured joint angles (rad, controller convention)."""
        q = np.asarray(self._read_joints(), dtype=float)
        if q.shape != (self.n_joints,) or not np.all(np.isfinite(q)):
            raise DeviceFault(f"robot reported invalid joint angles {q!r}")
        return JointAngles(value=q, source=self.address)

    def read_tool_pose(self) -> Pose | None:
        """Tool pose reported by the controller (m), or None if it reports none."""
        return self._read_tool_pose()

    def move_joints(self, target: np.ndarray, speed: float, acceleration: float) -> JointAngles:
        """Move to a joint target and return the angles reached.

        Parameters
        ----------
        target : array_like, shape (n,)
            Joint target (rad, controller convention). Limits are checked by
            :mod:`drivers.safety` before this call.
        speed : float
            Joint speed limit of the leading axis (rad/s), > 0.
        acceleration : float
            Joint acceleration limit (rad/s^2), > 0.
        """
        q = np.asarray(target, dtype=float)
        if q.shape != (self.n_joints,) or not np.all(np.isfinite(q)):
            raise ValueError(f"joint target must be {self.n_joints} finite angles (rad), got {q!r}")
        if not (speed > 0 and acceleration > 0):
            raise ValueError("speed and acceleration must be positive")
        self._move_joints(q, float(speed), float(acceleration))
        return self.read_joints()

    def stop(self) -> None:
        """Stop any motion now."""
        self._stop()

    def stop_quietly(self) -> None:
        """Stop any motion now, ignoring a DriverError: for a driver that is about to raise
        the error that made it stop (a timed-out motion), which must not be hidden."""
        try:
            self._stop()
        except DriverError:
            pass

    @abstractmethod
    def _read_joints(self) -> np.ndarray: ...

    def _read_tool_pose(self) -> Pose | None:
        return None

    @abstractmethod
    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None: ...

    @abstractmethod
    def _stop(self) -> None: ...

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(joints=self.n_joints, joint_unit="rad", convention="controller",
                 tool_pose_unit="m", tool_pose_frame="robot base")
        return d


class ForceTorqueSensor(Driver):
    """A 6-axis force/torque sensor.

    Subclasses implement ``_read_sample()`` returning one raw wrench
    [fx, fy, fz (N), mx, my, mz (N m)] in the sensor frame, blocking at most
    ``self.timeout`` seconds. The base class handles bias (tare), averaging,
    and detection of a frozen sensor (identical samples over a window).
    """

    role = "force_torque"
    #: nominal sample rate (Hz), used to turn a window in seconds into a count
    rate_hz: float = 100.0
    #: minimum number of bit-identical samples that is taken as a frozen sensor
    frozen_after: int = 10

    def __init__(self, address: str = "", *, timeout: float = 2.0) -> None:
        super().__init__(address, timeout=timeout)
        self.bias = np.zeros(6)
        #: entered around the dropping of stale samples at the start of each window; the
        #: simulated lab sets it to number its samples from there (no effect on hardware)
        self.window_guard: Callable[[], AbstractContextManager[Any]] = nullcontext

    def read_sample(self) -> np.ndarray:
        """One bias-corrected sample (N, N m), sensor frame."""
        s = np.asarray(self._read_sample(), dtype=float)
        if s.shape != (6,) or not np.all(np.isfinite(s)):
            raise DeviceFault(f"sensor returned an invalid sample {s!r}")
        return s - self.bias

    def _collect(self, samples: int) -> np.ndarray:
        if samples < 1:
            raise ValueError("need at least one sample")
        with self.window_guard():
            self._discard_buffered()
        deadline = time.monotonic() + self.timeout + samples / self.rate_hz * 2
        rows = []
        for _ in range(samples):
            rows.append(self.read_sample())
            if time.monotonic() > deadline:
                raise DeviceTimeout(f"{samples} samples took longer than expected")
        arr = np.array(rows)
        if samples >= self.frozen_after and np.all(arr == arr[0]):
            raise DeviceFault(f"sensor frozen: {samples} identical samples")
        return arr

    def tare(self, samples: int = 50) -> np.ndarray:
        """Average ``samples`` unloaded samples and use them as bias; returns it (N, N m)."""
        self.bias = np.zeros(6)
        self.bias = self._collect(samples).mean(axis=0)
        return self.bias.copy()

    def read_wrench(self, samples: int = 50) -> Wrench:
        """Averaged wrench over ``samples`` samples, with its spread, sensor frame."""
        return average_wrench(self._collect(samples), frame="sensor", source=self.address)

    def stream(self, count: int | None = None) -> Iterator[Wrench]:
        """Yield single-sample wrenches (sensor frame), ``count`` of them or forever."""
        n = 0
        while count is None or n < count:
            yield average_wrench(self.read_sample()[None, :], frame="sensor", source=self.address)
            n += 1

    @abstractmethod
    def _read_sample(self) -> np.ndarray: ...

    def _discard_buffered(self) -> None:
        """Drop samples queued before now (OS buffers), so a window holds fresh data only."""

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(unit="N, N m", frame="sensor", components="fx fy fz mx my mz",
                 rate_hz=self.rate_hz)
        return d


class PoseTracker(Driver):
    """Pose measurement: points, 6-DoF probe, or a rigid fit over several reflectors.

    Parameters
    ----------
    reflectors : dict of str to array_like, optional
        Reflector positions in the tool frame (m), at least three, for
        :meth:`measure_pose` by rigid fit when no 6-DoF probe is used.
    aim : callable, optional
        ``aim(name)`` is called before measuring reflector ``name`` (operator
        prompt on a real bench; the simulated lab points its beam).
    """

    role = "pose"

    def __init__(self, address: str = "", *, timeout: float = 5.0,
                 reflectors: dict[str, Any] | None = None,
                 aim: Callable[[str], None] | None = None) -> None:
        super().__init__(address, timeout=timeout)
        self.reflectors = {k: np.asarray(v, float) for k, v in (reflectors or {}).items()}
        if self.reflectors and len(self.reflectors) < 3:
            raise ValueError("a rigid fit needs at least three reflectors")
        self.aim = aim

    def measure_point(self, target: str = "") -> Point:
        """Measure one reflector (m, tracker frame)."""
        if target and self.aim is not None:
            self.aim(target)
        return self._measure_point(target)

    def measure_pose(self) -> Pose:
        """Tool pose in the tracker frame: 6-DoF probe, or fit of the reflectors."""
        if not self.reflectors:
            return self._measure_6dof()
        from drivers.frames import fit_rigid

        names = list(self.reflectors)
        pts = [self.measure_point(n) for n in names]
        model = np.array([self.reflectors[n] for n in names])
        meas = np.array([p.value for p in pts])
        T, rms = fit_rigid(model, meas)
        return Pose(value=T, frame="tracker", child="tool", residual=rms, source=self.address)

    @abstractmethod
    def _measure_point(self, target: str) -> Point: ...

    def _measure_6dof(self) -> Pose:
        raise DeviceFault(f"{type(self).__name__} has no 6-DoF probe; configure reflectors")

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(unit="m", frame="tracker", reflectors={k: v.tolist() for k, v in
                                                         self.reflectors.items()})
        return d


@dataclass(frozen=True)
class LoadCase:
    """A load to apply at the tool point.

    Attributes
    ----------
    name : str
        Label used in prompts and records.
    wrench : ndarray, shape (6,)
        [f (N), m (N m)] in the robot base frame at the tool point.
    """

    name: str
    wrench: np.ndarray = field(default_factory=lambda: np.zeros(6))


class LoadApplicator(Driver):
    """Applies and removes load cases (manual with an operator, or automated)."""

    role = "load"

    def apply(self, load: LoadCase) -> None:
        """Apply ``load``; returns when the load hangs on the tool."""
        w = np.asarray(load.wrench, dtype=float)
        if w.shape != (6,) or not np.all(np.isfinite(w)):
            raise ValueError(f"load {load.name!r}: wrench must be 6 finite numbers")
        self._apply(load)

    def remove(self) -> None:
        """Remove any applied load."""
        self._remove()

    @abstractmethod
    def _apply(self, load: LoadCase) -> None: ...

    @abstractmethod
    def _remove(self) -> None: ...

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        d.update(unit="N, N m", frame="robot base", point="tool point")
        return d
