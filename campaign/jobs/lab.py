"""The ``lab`` job: the simulated lab, its fake instruments on loopback, as one object.

:func:`run` resolves the options into :class:`drivers.sim.settings.LabSettings`
and starts a :class:`SimulatedLab`; stop it with :meth:`SimulatedLab.stop` or use
it as a context manager (``with run(options) as lab: ...``), which stops every
fake, the UR fake's process and the control channel on the way out, error or not.
Every fake binds 127.0.0.1.

A protocol file with a ``[campaign]`` table (as in ``protocols/``) makes the lab
simulate what it describes -- its robot and tool, the ``[fake_lab]`` true stiffness,
noise and seed, the reflectors of the pose instrument, and a fake for each
instrument driver of its ``[instruments]`` table -- exactly as ``campaign acquire
--fake`` does. A file without ``[campaign]`` is read as bare lab settings (the
:class:`~drivers.sim.settings.LabSettings` field names, optionally in a ``[lab]``
table).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from analysis.errors import InputError

#: the highest TCP port number
MAX_PORT = 65535


@dataclass(frozen=True)
class LabOptions:
    """protocol: a campaign protocol or a lab settings file (TOML/YAML; None: the
    defaults); robot: the robot model of bare lab settings (a campaign protocol names
    its own); seed: seed of the simulated noise (None: the file's); time_scale:
    simulated time runs this many times faster than the wall clock (None: the file's);
    instruments: the fakes to start by driver name (None: all, or the protocol's);
    can_interface: where the Net CAN fake sits, ``socketcand`` (a server on 127.0.0.1)
    or ``virtual`` (in-process); control_port: TCP port of the control channel on
    127.0.0.1, whose ``addresses`` command lists every fake (0: a free port); ports:
    fixed TCP ports of fakes by driver name (those of
    :data:`drivers.sim.lab.FIXED_PORTS`; the others take free ports)."""

    protocol: Path | None = None
    robot: str | None = None
    seed: int | None = None
    time_scale: float | None = None
    instruments: Sequence[str] | None = None
    can_interface: str | None = None
    control_port: int = 0
    ports: Mapping[str, int] | None = None


class SimulatedLab:
    """A started simulated lab: :attr:`addresses` (driver name -> URL on 127.0.0.1, plus
    ``control``), :attr:`description` (what it simulates, one line each) and
    :attr:`notes` (fakes that could not start)."""

    def __init__(self, settings: Any, probe: bool, control_port: int = 0,
                 ports: Mapping[str, int] | None = None) -> None:
        from drivers.sim.lab import FIXED_PORTS, Lab

        self.settings = settings
        self.probe = probe
        ports = dict(ports or {})
        other = sorted(set(ports) - set(FIXED_PORTS))
        if other:
            raise InputError(f"{', '.join(other)} cannot take a fixed port (only "
                             f"{', '.join(FIXED_PORTS)} can)", where="--port")
        try:
            self.lab = Lab(settings, control_port=control_port, ports=ports)
        except ValueError as err:
            raise InputError(str(err), where="lab settings") from err
        except OSError as err:  # the control port is taken
            raise InputError(f"port {control_port} on 127.0.0.1: {err.strerror or err}",
                             where="--control-port") from None
        self.addresses: dict[str, str] = {}

    def start(self) -> dict[str, str]:
        """Start every fake; the addresses (also :attr:`addresses`)."""
        try:
            self.addresses = dict(self.lab.start())
        except OSError as err:  # a fixed port of a fake is taken
            self.lab.stop()
            raise InputError(f"a fake cannot listen on its port ({err.strerror or err})",
                             where="--port") from None
        except BaseException:
            self.lab.stop()
            raise
        if self.probe:  # the protocol's pose noise is that of a 6-DoF probe
            for fake in self.lab.fakes:
                if getattr(fake, "driver", "") == "emscon":
                    fake.mode = "6dof"
        return self.addresses

    @property
    def notes(self) -> list[str]:
        return list(self.lab.notes)

    @property
    def description(self) -> list[str]:
        return describe(self.settings, self.probe)

    def wait(self) -> None:
        """Block until a ``shutdown`` command on the control channel (or :meth:`stop`)."""
        self.lab.wait()

    def stop(self) -> None:
        """Stop every fake, the UR fake's process and the control channel."""
        self.lab.stop()

    def __enter__(self) -> SimulatedLab:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _read_protocol(path: Path) -> dict[str, Any]:
    """Parse a protocol file (TOML or YAML, UTF-8) into a plain dict."""
    from analysis.file_errors import read_mapping_file

    if not path.is_file():
        raise InputError("protocol file not found", where=str(path))
    return read_mapping_file(path, "protocol file")[0]


def _protocol_settings(path: Path, o: LabOptions, instruments: tuple[str, ...] | None):
    """Lab settings of a campaign protocol, plus the emScon mode its pose noise implies."""
    from campaign.acquire.instruments import lab_settings
    from campaign.protocol import load_protocol

    protocol = load_protocol(path)
    settings = lab_settings(protocol, o.time_scale)
    changes: dict[str, Any] = {}
    if o.seed is not None:
        changes["seed"] = o.seed
    if instruments is not None:
        changes["instruments"] = instruments
    if o.can_interface is not None:
        changes["can_interface"] = o.can_interface
    if changes:
        settings = dataclasses.replace(settings, **changes)
    # without reflectors_mm the protocol's pose noise is that of a 6-DoF probe
    probe = protocol.instruments["pose"].driver == "emscon" and protocol.reflectors() is None
    return settings, probe


def settings_of(o: LabOptions) -> tuple[Any, bool]:
    """(LabSettings, 6-DoF probe poses) of the options; InputError naming the option."""
    from drivers.sim.settings import settings_from_protocol

    if not 0 <= o.control_port <= MAX_PORT:
        raise InputError(f"expected a port number 0..{MAX_PORT}", where="--control-port")
    for name, port in (o.ports or {}).items():
        if not (isinstance(port, int) and 0 < port <= MAX_PORT):
            raise InputError(f"{name}: expected a port number 1..{MAX_PORT}, got {port!r}",
                             where="--port")
    path = None if o.protocol is None else Path(o.protocol)
    base = _read_protocol(path) if path is not None else {}
    chosen = None if o.instruments is None else tuple(
        s.strip() for s in o.instruments if s.strip()) or None
    if path is not None and "campaign" in base:
        if o.robot is not None:
            raise InputError("the protocol names the robot ([campaign] robot): drop --robot",
                             where="--robot")
        return _protocol_settings(path, o, chosen)
    return settings_from_protocol(base, seed=o.seed, time_scale=o.time_scale, robot=o.robot,
                                  instruments=chosen, can_interface=o.can_interface), False


def describe(settings: Any, probe: bool) -> list[str]:
    """What the lab simulates, one line each (units in each line)."""
    import math

    from analysis.report.formatting import k_kNm

    k = ", ".join(k_kNm(v) for v in settings.true_joint_stiffness)
    return [
        f"robot {settings.robot}, tool xyz_mm "
        f"{[round(v * 1e3, 3) for v in settings.tool_xyz]}, rpy_deg "
        f"{[round(math.degrees(v), 3) for v in settings.tool_rpy]}",
        f"true joint stiffness (kN m/rad): {k}",
        f"noise: tracker {settings.tracker_noise * 1e6:g} um, probe rotation "
        f"{settings.tracker_angle_noise * 1e6:g} urad, force {settings.force_noise:g} N, "
        f"torque {settings.torque_noise:g} N m, encoders {settings.encoder_noise * 1e6:g} urad",
        "reflectors (mm, tool frame): " + ", ".join(
            f"{name} {[round(c * 1e3, 3) for c in xyz]}"
            for name, xyz in settings.reflectors.items()),
        f"instruments: {', '.join(settings.instruments)}"
        + ("; emscon serves 6-DoF probe poses" if probe else ""),
        f"seed {settings.seed}, time scale {settings.time_scale:g}",
    ]


def run(o: LabOptions) -> SimulatedLab:
    """The simulated lab of ``o``, started (stop it, or leave its ``with`` block)."""
    settings, probe = settings_of(o)
    lab = SimulatedLab(settings, probe, o.control_port, o.ports)
    lab.start()
    return lab
