"""The four instruments of a run (robot, force/torque sensor, tracker, load), real or fake.

With ``fake=True`` the simulated lab (:mod:`drivers.sim.lab`) is started and
the protocol's *real* drivers are pointed at its loopback servers; a manual
robot or manual load is served by the lab's simulated operator. Without it,
the protocol's addresses are used as they are.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from analysis.errors import InputError
from campaign.protocol import DEG, Protocol
from drivers.errors import DriverError
from drivers.registry import open_driver
from drivers.roles import ForceTorqueSensor, LoadApplicator, PoseTracker, RobotController

ROLES = ("robot", "force_torque", "pose", "load")
MANUAL = ("manual", "manual-load")


@dataclass
class Instruments:
    """Connected drivers of one run, and the simulated lab behind them if any."""

    robot: RobotController
    ft: ForceTorqueSensor
    tracker: PoseTracker
    load: LoadApplicator
    drivers: dict[str, str]
    lab: Any = None
    operator: Any = None
    sensor_mount: np.ndarray = field(default_factory=lambda: np.eye(4))
    clients: list[Any] = field(default_factory=list)

    @property
    def automated_load(self) -> bool:
        """True when the load can be removed without a person (automated or simulated)."""
        return self.drivers["load"] not in MANUAL or self.operator is not None

    @property
    def lab_addresses(self) -> dict[str, str]:
        return dict(self.lab.addresses) if self.lab is not None else {}

    def devices(self) -> list[Any]:
        return [self.robot, self.ft, self.tracker, self.load]

    def connect(self) -> None:
        for role, dev in zip(ROLES, self.devices(), strict=True):
            try:
                dev.connect()
            except DriverError as err:
                raise InputError(f"cannot connect: {err}",
                                 where=f"instruments.{role} ({self.drivers[role]})") from err

    def reconnect(self) -> None:
        """Close and reopen every link (after a fault, before the retry)."""
        for dev in self.devices():
            try:
                dev.close()
            except (DriverError, OSError):
                pass
        for dev in self.devices():
            dev.connect()

    def close(self) -> None:
        for dev in self.devices():
            try:
                dev.close()
            except (DriverError, OSError):
                pass
        for client in [*self.clients, self.operator]:
            if client is not None:
                try:
                    client.close()
                except OSError:
                    pass
        self.clients, self.operator = [], None
        if self.lab is not None:
            self.lab.stop()
            self.lab = None

    def describe(self) -> dict[str, Any]:
        """role -> driver name, address, units and frames (from each driver's ``describe()``)."""
        out = {}
        for role, dev in zip(ROLES, self.devices(), strict=True):
            d = dict(dev.describe())
            d["registry_name"] = self.drivers[role]
            out[role] = d
        return out

    def mark(self, test_id: int | None, repeat: int | None, attempt: int | None,
             phase: str) -> None:
        """Tell the simulated lab (if any) which test and phase the readings belong to,
        so each is drawn from its own seeded generator (no effect on hardware)."""
        if self.lab is not None:
            self.lab.mark(*(0 if v is None else int(v) for v in (test_id, repeat, attempt)),
                          phase)

    def read_point(self) -> np.ndarray:
        """One position (m, tracker frame) of the tool for settling detection."""
        if self.tracker.reflectors:
            name = next(iter(self.tracker.reflectors))
            return np.asarray(self.tracker.measure_point(name).value, dtype=float)
        return np.asarray(self.tracker.measure_pose().value, dtype=float)[:3, 3]


def _spec(protocol: Protocol, role: str):
    spec = protocol.instruments.get(role)
    if spec is None:
        raise InputError(f"the protocol names no '{role}' instrument",
                         where=protocol.where("instruments"))
    return spec


def sensor_mount(protocol: Protocol) -> np.ndarray:
    """Force sensor frame in the tool frame (4x4, m) from the protocol's mount keys."""
    from campaign.acquire.geometry import mount_matrix

    spec = _spec(protocol, "force_torque")
    xyz = None if spec.mount_xyz_mm is None else np.array(spec.mount_xyz_mm) * 1e-3
    rpy = None if spec.mount_rpy_deg is None else np.array(spec.mount_rpy_deg) * DEG
    return mount_matrix(xyz, rpy)


def pose_options(protocol: Protocol) -> dict[str, Any]:
    """Options of the pose instrument, ``reflectors_mm`` turned into ``reflectors`` (m)."""
    options = dict(_spec(protocol, "pose").options)
    options.pop("reflectors_mm", None)
    reflectors = protocol.reflectors()
    if reflectors is not None:
        options["reflectors"] = reflectors
    return options


def lab_settings(protocol: Protocol, time_scale: float | None):
    """Settings of the simulated lab from the protocol's ``[fake_lab]`` and its instruments."""
    from drivers.sim.settings import settings_from_protocol

    if protocol.lab is None:
        raise InputError("--fake needs a [fake_lab] section with the true joint stiffness",
                         where=protocol.where("fake_lab"))
    fakes = []
    for role in ("force_torque", "pose"):
        fakes.append(_spec(protocol, role).driver)
    if _spec(protocol, "robot").driver not in MANUAL:
        fakes.append("robot")
    mount = sensor_mount(protocol)
    from drivers.frames import matrix_to_rotvec

    tool = protocol.tool
    reflectors = pose_options(protocol).get("reflectors")
    return settings_from_protocol(protocol.lab, time_scale=time_scale, instruments=tuple(fakes),
                                  reflectors=reflectors,
                                  tool_xyz=tuple(float(v) * 1e-3 for v in tool.xyz_mm),
                                  tool_rpy=tuple(math.radians(float(v)) for v in tool.rpy_deg),
                                  sensor_offset=tuple(mount[:3, 3]),
                                  sensor_rotation=tuple(matrix_to_rotvec(mount[:3, :3])))


def open_instruments(protocol: Protocol, fake: bool, time_scale: float | None = None
                     ) -> Instruments:
    """Build the drivers (and start the simulated lab for ``fake``); not yet connected."""
    drivers = {role: _spec(protocol, role).driver for role in ROLES}
    lab = operator = None
    clients: list[Any] = []
    addresses = {role: _spec(protocol, role).address for role in ROLES}
    options: dict[str, dict[str, Any]] = {role: dict(_spec(protocol, role).options)
                                          for role in ROLES}
    options["pose"] = pose_options(protocol)
    if fake:
        from drivers.sim.control import LabClient
        from drivers.sim.lab import Lab
        from drivers.sim.lab_load import LabOperator

        settings = lab_settings(protocol, time_scale)
        lab = Lab(settings)
        try:
            lab.start()
            for role in ROLES:
                name = drivers[role]
                if name not in lab.addresses:
                    raise InputError(f"the simulated lab has no fake for driver {name!r} "
                                     f"({'; '.join(lab.notes) or 'not started'})",
                                     where=protocol.where("instruments", role, "driver"))
                addresses[role] = lab.addresses[name]
            control = lab.addresses["control"]
            if drivers["pose"] == "emscon":
                # the protocol's pose noise is that of a 6-DoF probe: serve probe poses
                for fake_server in lab.fakes:
                    if getattr(fake_server, "driver", "") == "emscon":
                        fake_server.mode = "6dof"
            else:  # point-only instruments: a rigid fit over the reflectors
                options["pose"]["reflectors"] = dict(settings.reflectors)
                aim_client = LabClient(control)
                clients.append(aim_client)
                options["pose"]["aim"] = lambda name: aim_client.call("aim", target=name)
            if drivers["robot"] in MANUAL or drivers["load"] in MANUAL:
                operator = LabOperator(control, speed=np.deg2rad(
                    protocol.safety.max_joint_speed_deg_s))
                for role in ("robot", "load"):
                    if drivers[role] in MANUAL:
                        options[role].update(ask=operator.ask, say=operator.say)
        except BaseException:
            lab.stop()
            raise
    built = {}
    try:
        for role in ROLES:
            built[role] = open_driver(drivers[role], addresses[role], **options[role])
    except DriverError as err:
        if lab is not None:
            lab.stop()
        raise InputError(str(err), where=protocol.where("instruments", role)) from err
    if lab is not None:
        guard = lab.window_guard(drivers["force_torque"])
        if guard is not None:
            built["force_torque"].window_guard = guard
    return Instruments(robot=built["robot"], ft=built["force_torque"], tracker=built["pose"],
                       load=built["load"], drivers=drivers, lab=lab, operator=operator,
                       sensor_mount=sensor_mount(protocol), clients=clients)
