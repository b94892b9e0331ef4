"""``campaign lab --fake``: run the simulated lab and print the addresses of its instruments.

Each line of output is ``name=address`` (``name`` is a driver registry name,
or ``control`` for the lab's control channel), then ``ready``. The lab runs
until interrupted (Ctrl-C) or until a ``shutdown`` command on the control channel.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import typer

from analysis.errors import InputError


def _read_protocol(path: Path) -> dict[str, Any]:
    """Parse a protocol file (TOML or YAML) into a plain dict."""
    if not path.is_file():
        raise InputError("protocol file not found", where=str(path))
    text = path.read_text(encoding="utf-8")
    try:
        if path.suffix.lower() == ".toml":
            data = tomllib.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text)
    except (tomllib.TOMLDecodeError, ValueError) as err:
        raise InputError(f"cannot parse: {err}", where=str(path)) from err
    except Exception as err:  # yaml.YAMLError without importing yaml at module level
        raise InputError(f"cannot parse: {err}", where=str(path)) from err
    if not isinstance(data, dict):
        raise InputError("expected a table of settings at the top level", where=str(path))
    return data


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
        can_interface: str | None = typer.Option(None, "--can-interface", help="python-can "
                                                 "interface of the Net CAN fake."),
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
        settings = settings_from_protocol(base, seed=seed, time_scale=time_scale, robot=robot,
                                          instruments=chosen, can_interface=can_interface)
        try:
            sim = Lab(settings)
        except ValueError as err:
            raise InputError(str(err), where="lab settings") from err
        try:
            for name, url in sim.start().items():
                typer.echo(f"{name}={url}")
            for note in sim.notes:
                typer.echo(f"note: {note}", err=True)
            typer.echo("ready")
            sim.wait()
        except KeyboardInterrupt:
            pass
        finally:
            sim.stop()
