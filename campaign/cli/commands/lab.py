"""``campaign lab --fake``: run the simulated lab and print the addresses of its instruments.

Each line of output is ``name=address`` (``name`` is a driver registry name,
or ``control`` for the lab's control channel), then ``ready``. The lab runs
until interrupted (Ctrl-C) or until a ``shutdown`` command on the control channel.
What ``--protocol`` may hold, and the lab itself: :mod:`campaign.jobs.lab`; this
module parses the options and presents.
"""

from __future__ import annotations

from pathlib import Path

import typer

from analysis.errors import InputError


def _ports(items: list[str]) -> dict[str, int]:
    """``NAME=PORT`` items of ``--port`` as {driver name: port}."""
    ports = {}
    for item in items:
        name, sep, text = item.partition("=")
        try:
            ports[name.strip()] = int(text)
        except ValueError:
            raise InputError(f"expected NAME=PORT, got {item!r}", where="--port") from None
        if not sep or not name.strip():
            raise InputError(f"expected NAME=PORT, got {item!r}", where="--port")
    return ports


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
        control_port: int = typer.Option(0, "--control-port", help="TCP port of the control "
                                         "channel on 127.0.0.1 (default: a free one); its "
                                         "addresses command lists the fakes."),
        port: list[str] = typer.Option(  # noqa: B008 (typer's way of a repeatable option)
            [], "--port", help="NAME=PORT: a fixed port of the fake NAME (emscon, geocom, "
            "kuka-kvp, fanuc-rmi; the others take free ones); repeatable."),
    ) -> None:
        """Start fake instruments on loopback that speak the real protocols."""
        if not fake:
            raise InputError("only the simulated lab can be started here: add --fake",
                             where="campaign lab")
        from campaign.cli.terminal import echo
        from campaign.jobs.lab import LabOptions, run

        chosen = None if not instruments else instruments.split(",")
        sim = run(LabOptions(protocol, robot, seed, time_scale, chosen, can_interface,
                             control_port, _ports(port)))
        with sim:
            try:
                for name, url in sim.addresses.items():
                    typer.echo(f"{name}={url}")
                # name=url lines stay whole (scripts read them); these are for people
                for line in sim.description:
                    echo(f"lab: {line}", err=True)
                for note in sim.notes:
                    echo(f"note: {note}", err=True)
                typer.echo("ready")
                sim.wait()
            except KeyboardInterrupt:
                pass
