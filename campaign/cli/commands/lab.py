"""``campaign lab --fake``: run the simulated lab and print the addresses of its instruments.

Each line of output is ``name=address`` (``name`` is a driver registry name,
or ``control`` for the lab's control channel), then ``ready``. The lab runs
until interrupted (Ctrl-C) or until a ``shutdown`` command on the control channel.

``--protocol`` takes a campaign protocol (a file with a ``[campaign]`` table, as in
``protocols/``): the lab then simulates what it describes -- its robot and tool, the
``[fake_lab]`` true stiffness, noise and seed, the reflectors of the pose instrument,
and a fake for each instrument driver of its ``[instruments]`` table -- exactly as
``campaign acquire --fake`` does. A file without ``[campaign]`` is read as bare lab
settings (the :class:`drivers.sim.settings.LabSettings` field names, optionally in a
``[lab]`` table).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import typer

from analysis.errors import InputError


def _read_protocol(path: Path) -> dict[str, Any]:
    """Parse a protocol file (TOML or YAML, UTF-8) into a plain dict."""
    from analysis.file_errors import read_mapping_file

    if not path.is_file():
        raise InputError("protocol file not found", where=str(path))
    return read_mapping_file(path, "protocol file")[0]


def _protocol_settings(path: Path, seed: int | None, time_scale: float | None,
                       instruments: tuple[str, ...] | None, can_interface: str | None):
    """Lab settings of a campaign protocol, plus the emScon mode its pose noise implies."""
    import dataclasses

    from campaign.acquire.instruments import lab_settings
    from campaign.protocol import load_protocol

    protocol = load_protocol(path)
    settings = lab_settings(protocol, time_scale)
    changes: dict[str, Any] = {}
    if seed is not None:
        changes["seed"] = seed
    if instruments is not None:
        changes["instruments"] = instruments
    if can_interface is not None:
        changes["can_interface"] = can_interface
    if changes:
        settings = dataclasses.replace(settings, **changes)
    # without reflectors_mm the protocol's pose noise is that of a 6-DoF probe
    probe = protocol.instruments["pose"].driver == "emscon" and protocol.reflectors() is None
    return protocol, settings, probe


def _describe(settings: Any, probe: bool) -> list[str]:
    """What the lab simulates, one line each (printed on stderr)."""
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


def register(app: typer.Typer) -> None:
    """Add the ``lab`` command to ``app``."""

    @app.command("lab")
    def lab(
        fake: bool = typer.Option(False, "--fake", help="Run the simulated lab (required)."),
        protocol: Path | None = typer.Option(None, "--protocol", help="Protocol file "
                                             "(TOML/YAML) with the true stiffness and noise."),
        seed: int | None = typer.Option(None, "--seed", help="Seed of the simulated noise."),
        time_scale: float | None = typer.Option(None, "--time-scale", help="Simulated time "
                                                "runs this many times faster than real time."),
        robot: str | None = typer.Option(None, "--robot", help="Robot model (default kr240-2)."),
        instruments: str | None = typer.Option(None, "--instruments", help="Comma-separated "
                                               "fakes to start (default: all)."),
        can_interface: str | None = typer.Option(None, "--can-interface", help="Where the "
                                                 "Net CAN fake sits: socketcand (a server on "
                                                 "127.0.0.1, default) or virtual (in-process)."),
    ) -> None:
        """Start fake instruments on loopback that speak the real protocols."""
        if not fake:
            raise InputError("only the simulated lab can be started here: add --fake",
                             where="campaign lab")
        from drivers.sim.lab import Lab
        from drivers.sim.settings import settings_from_protocol

        base = _read_protocol(protocol) if protocol is not None else {}
        chosen = tuple(s.strip() for s in instruments.split(",") if s.strip()) \
            if instruments else None
        probe = False
        if protocol is not None and "campaign" in base:
            if robot is not None:
                raise InputError("the protocol names the robot ([campaign] robot): drop --robot",
                                 where="--robot")
            _, settings, probe = _protocol_settings(protocol, seed, time_scale, chosen,
                                                    can_interface)
        else:
            settings = settings_from_protocol(base, seed=seed, time_scale=time_scale,
                                              robot=robot, instruments=chosen,
                                              can_interface=can_interface)
        try:
            sim = Lab(settings)
        except ValueError as err:
            raise InputError(str(err), where="lab settings") from err
        try:
            addresses = sim.start()
            if probe:
                for fake_server in sim.fakes:
                    if getattr(fake_server, "driver", "") == "emscon":
                        fake_server.mode = "6dof"
            for name, url in addresses.items():
                typer.echo(f"{name}={url}")
            # name=url lines stay whole (scripts read them); these are for people
            from campaign.cli.common import echo

            for line in _describe(settings, probe):
                echo(f"lab: {line}", err=True)
            for note in sim.notes:
                echo(f"note: {note}", err=True)
            typer.echo("ready")
            sim.wait()
        except KeyboardInterrupt:
            pass
        finally:
            sim.stop()
