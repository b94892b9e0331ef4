"""``campaign robots``: list the built-in models, or show one model's table."""

from __future__ import annotations

import numpy as np
import typer
from rich.console import Console
from rich.table import Table


def register(app: typer.Typer) -> None:
    @app.command("robots")
    def robots(
        name: str = typer.Argument(None, help="Show this model (built-in name or file)."),
        tip: str = typer.Option(None, help="Tool frame of a URDF."),
    ) -> None:
        """List built-in robot models, or show one model's joints, limits and sources."""
        from analysis.model.robots import builtin_names, load_robot  # pinocchio: lazily

        console = Console()
        if name is None:
            table = Table(title="Built-in robot models")
            for col in ("name", "model", "convention", "nominal stiffness", "zones"):
                table.add_column(col)
            for key in builtin_names():
                r = load_robot(key)
                table.add_row(key, r.name, r.convention,
                              "yes" if r.nominal_stiffness is not None else "no",
                              str(len(r.zones)))
            console.print(table)
            return
        r = load_robot(name, tip)
        table = Table(title=f"{r.name} ({r.source_file})")
        for col in ("joint", "lower (deg, model)", "upper (deg, model)",
                    "pendant = sign*q + offset (+ coupling)", "nominal k (N m/rad)"):
            table.add_column(col, justify="right")
        for j in range(r.n):
            k = "-" if r.nominal_stiffness is None else f"{r.nominal_stiffness[j]:,.0f}"
            table.add_row(
                str(j + 1), f"{np.degrees(r.lower[j]):.1f}", f"{np.degrees(r.upper[j]):.1f}",
                f"{int(r.controller_sign[j]):+d} q {np.degrees(r.controller_offset[j]):+.1f}"
                + "".join(f" {c:+g} q{k + 1}" for k, c in enumerate(r.controller_coupling[j])
                          if c),
                k,
            )
        console.print(table)
        L = r.characteristic_length
        console.print(f"characteristic length: {'not given' if L is None else f'{L:.3f} m'}")
        for zone in r.zones:
            ranges = ", ".join(
                f"q{j + 1} {np.degrees(a):.0f}..{np.degrees(b):.0f} deg"
                for j, (a, b) in zone.ranges.items()
            )
            console.print(f"{zone.name}: {ranges}")
        if r.notes:
            console.print(f"[bold]note[/bold]: {r.notes}")
        for key, text in r.sources.items():
            console.print(f"[bold]source[/bold] {key}: {text}")

