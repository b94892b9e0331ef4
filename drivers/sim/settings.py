"""Settings of the simulated lab, with defaults for the KUKA KR240-2 of Dumas et al. (2011)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from analysis.errors import InputError

#: True joint stiffness of the KR240-2 (N m/rad), Dumas et al. 2011, Table 2.
KR240_STIFFNESS = (1409800.0, 400760.0, 935280.0, 360000.0, 370000.0, 380000.0)

#: Every fake the lab can start; "robot" picks ``ur`` for UR robots, ``fanuc-rmi`` for FANUC,
#: ``abb-rws`` and ``abb-rws2`` (RobotWare 6 and 7) for ABB, else ``kuka-kvp``.
ALL_INSTRUMENTS = ("ati-netft", "robotiq-ft300", "ati-netcan", "emscon", "geocom", "robot")


@dataclass
class LabSettings:
    """What the simulated lab simulates (SI units).

    Attributes
    ----------
    robot : str
        Robot spec for :func:`analysis.model.robots.load_robot`.
    true_joint_stiffness : tuple of float
        Joint stiffness (N m/rad) used to deflect the robot under load.
    seed : int
        Seed of every random draw of the world (noise).
    time_scale : float
        Simulated time runs this many times faster than the wall clock
        (motions and settling are shorter by this factor).
    settle_time : float
        Time constant (s, simulated) of the exponential settling after a load change.
    force_noise, torque_noise : float
        Standard deviation per F/T sample (N, N m).
    tracker_noise : float
        Standard deviation per tracker coordinate (m).
    tracker_angle_noise : float
        Standard deviation of 6-DoF probe rotation (rad).
    encoder_noise : float
        Standard deviation of reported joint angles (rad).
    instruments : tuple of str
        Fakes to start, from :data:`ALL_INSTRUMENTS`.
    home : tuple of float or None
        Initial joint angles (rad, controller convention); None = middle of the limits.
    reflectors : dict of str to tuple
        Reflector positions in the tool frame (m).
    sensor_offset : tuple of float
        Sensor origin in the tool frame (m).
    sensor_rotation : tuple of float
        Rotation vector (rad) of the sensor axes relative to the tool frame.
    tool_xyz, tool_rpy : tuple of float
        Tool point P and tool frame in the robot model's flange frame (m; fixed-axis
        roll-pitch-yaw, rad), as the protocol's ``[tool]``; the load acts at P and the
        reflectors, the probe and the sensor are placed in the tool frame.
    tracker_position : tuple of float
        Robot-base origin as seen in the tracker frame (m).
    tracker_yaw : float
        Rotation (rad) about the vertical of the robot base frame seen from the tracker.
    can_interface : str
        Where the Net CAN fake sits: ``socketcand`` (a socketcand server on
        127.0.0.1, reachable from other processes) or ``virtual`` (python-can's
        in-process bus). Both stay on this host.
    gravity, lost_motion, links, compensator : the real-arm effects of the protocol's
        ``[fake_lab]`` (:mod:`analysis.kinetostatics.realistic_lab`: "off"/"flanks"/"on";
        (n,) rad full dead band; link compliances; axis compensator), each off by default.
    tracker_drift : tuple of float or None
        Drift (m/s of the lab's simulated time, tracker frame) added to every tracker reading.
    ft_drift : tuple of float or None
        Zero drift of the F/T sensor (N/s, N m/s of the lab's simulated time, sensor frame).
    """

    robot: str = "kr240-2"
    true_joint_stiffness: tuple[float, ...] = KR240_STIFFNESS
    seed: int = 0
    time_scale: float = 1.0
    settle_time: float = 0.5
    force_noise: float = 0.5
    torque_noise: float = 0.05
    tracker_noise: float = 10e-6
    tracker_angle_noise: float = 10e-6
    encoder_noise: float = 0.0
    instruments: tuple[str, ...] = ALL_INSTRUMENTS
    home: tuple[float, ...] | None = None
    reflectors: dict[str, tuple[float, float, float]] = field(default_factory=lambda: {
        "P": (0.0, 0.0, 0.0),
        "R1": (0.12, 0.0, -0.05),
        "R2": (0.0, 0.12, -0.05),
        "R3": (-0.08, -0.08, -0.02),
    })
    sensor_offset: tuple[float, float, float] = (0.0, 0.0, -0.08)
    sensor_rotation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tool_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tracker_position: tuple[float, float, float] = (-3.0, 1.0, -0.5)
    tracker_yaw: float = 0.5
    can_interface: str = "socketcand"
    gravity: str = "off"
    lost_motion: tuple[float, ...] | None = None
    links: tuple[dict, ...] = ()
    compensator: dict | None = None
    tracker_drift: tuple[float, float, float] | None = None
    ft_drift: tuple[float, ...] | None = None

    def effects(self) -> dict[str, Any]:
        """The real-arm effects, for :func:`analysis.kinetostatics.realistic_lab.realistic_lab`."""
        return {"gravity": self.gravity, "lost_motion": self.lost_motion,
                "links": self.links, "compensator": self.compensator}

    def __post_init__(self) -> None:
        if self.time_scale <= 0:
            raise InputError("time scale must be positive", where="--time-scale")
        if self.settle_time < 0:
            raise InputError("settle time must be >= 0", where="settle_time")
        for name in ("force_noise", "torque_noise", "tracker_noise", "tracker_angle_noise",
                     "encoder_noise"):
            if getattr(self, name) < 0:
                raise InputError("noise must be >= 0", where=name)
        if any(k <= 0 for k in self.true_joint_stiffness):
            raise InputError("true joint stiffness must be positive (N m/rad)",
                             where="true_joint_stiffness")
        unknown = set(self.instruments) - set(ALL_INSTRUMENTS)
        if unknown:
            raise InputError(f"unknown instruments {sorted(unknown)}; known: "
                             f"{', '.join(ALL_INSTRUMENTS)}", where="instruments")
        if self.can_interface not in ("socketcand", "virtual"):
            raise InputError(f"CAN interface {self.can_interface!r} of the Net CAN fake: use "
                             "socketcand or virtual (both stay on this host)",
                             where="can_interface")
        if len(self.reflectors) < 3:
            raise InputError("need at least three reflectors", where="reflectors")
        if self.gravity not in ("off", "flanks", "on"):
            raise InputError(f"gravity {self.gravity!r}: expected off, flanks or on",
                             where="gravity")
        for name, size in (("tracker_drift", 3), ("ft_drift", 6)):
            value = getattr(self, name)
            if value is not None and len(value) != size:
                raise InputError(f"{name}: expected {size} numbers", where=name)


def settings_from_protocol(protocol: Mapping[str, Any] | Any, **overrides: Any) -> LabSettings:
    """Build :class:`LabSettings` from a parsed protocol (mapping or object with attributes).

    Only keys that name a :class:`LabSettings` field are used; a ``lab`` or
    ``simulation`` sub-table, if present, is read too. ``overrides`` (e.g. from
    the command line) win.
    """
    names = {f.name for f in fields(LabSettings)}
    if not isinstance(protocol, Mapping):
        protocol = {n: getattr(protocol, n) for n in dir(protocol) if n in names
                    or n in ("lab", "simulation")}
    values: dict[str, Any] = {}
    for key in ("lab", "simulation"):
        sub = protocol.get(key)
        if isinstance(sub, Mapping):
            values.update({k: v for k, v in sub.items() if k in names})
    values.update({k: v for k, v in protocol.items() if k in names})
    values.update({k: v for k, v in overrides.items() if v is not None})
    for key in ("true_joint_stiffness", "instruments", "home", "sensor_offset",
                "sensor_rotation", "tracker_position", "tool_xyz", "tool_rpy", "lost_motion",
                "links", "tracker_drift", "ft_drift"):
        if values.get(key) is not None:
            values[key] = tuple(values[key])
    try:
        return LabSettings(**values)
    except TypeError as err:
        raise InputError(f"bad lab settings: {err}", where="protocol") from err
