"""``campaign robots``: list the built-in models, or show one model's table."""

from __future__ import annotations

import numpy as np
import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from analysis.report.formatting import k_kNm
from campaign.cli_common import print_json, print_wrapped

#: how messages name the positional argument of ``campaign robots NAME``
NAME_WHERE = "NAME (argument of campaign robots)"


def robot_dict(r) -> dict:
    """A robot model as JSON (SI units, radians; the keys' suffixes say so)."""
    return {
        "name": r.name, "source_file": str(r.source_file) if r.source_file else None,
        "convention": r.convention, "joints": r.n,
        "lower_rad": r.lower.tolist(), "upper_rad": r.upper.tolist(),
        "controller_sign": [int(v) for v in r.controller_sign],
        "controller_offset_rad": r.controller_offset.tolist(),
        "controller_coupling": np.asarray(r.controller_coupling).tolist(),
        "nominal_stiffness_Nm_per_rad": None if r.nominal_stiffness is None
        else np.asarray(r.nominal_stiffness, float).tolist(),
        "characteristic_length_m": r.characteristic_length,
        "zones": [{"name": z.name, "ranges_rad": {f"q{j + 1}": [float(a), float(b)]
                                                  for j, (a, b) in z.ranges.items()}}
                  for z in r.zones],
        "notes": r.notes or None, "sources": dict(r.sources),
    }


def register(app: typer.Typer) -> None:
    @app.command("robots")
    def robots(
        name: str = typer.Argument(None, help="Show this model (built-in name or file)."),
        tip: str = typer.Option(None, help="Tool frame of a URDF."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units, rad)."),
    ) -> None:
        """List built-in robot models, or show one model's joints, limits and sources."""
        from analysis.model.robots import builtin_names, load_robot  # pinocchio: lazily

        console = Console(width=min(Console().width, 80))  # fits an 80-column terminal
        if as_json:
            if name is None:
                print_json({"robots": [{"key": key, **robot_dict(load_robot(key))}
                                       for key in builtin_names()]})
            else:
                print_json(robot_dict(load_robot(name, tip, where=NAME_WHERE)))
            return
        if name is None:
            table = Table(title="Built-in robot models")
            for col in ("name", "model", "convention", "nominal stiffness", "zones"):
                table.add_column(col)
            for key in builtin_names():
                r = load_robot(key)
                table.add_row(key, escape(r.name), r.convention,
                              "yes" if r.nominal_stiffness is not None else "no",
                              str(len(r.zones)))
            console.print(table)
            return
        r = load_robot(name, tip, where=NAME_WHERE)
        table = Table(title=escape(f"{r.name} ({r.source_file})"),
                      caption="angles in the model convention; pendant angle = sign q + "
                      "offset (+ coupling)")
        for col in ("joint", "lower (deg)", "upper (deg)", "pendant (deg)",
                    "nominal k (kN m/rad)"):
            table.add_column(col, justify="right")
        for j in range(r.n):
            k = "-" if r.nominal_stiffness is None else k_kNm(r.nominal_stiffness[j])
            table.add_row(
                str(j + 1), f"{np.degrees(r.lower[j]):.1f}", f"{np.degrees(r.upper[j]):.1f}",
                f"{int(r.controller_sign[j]):+d} q {np.degrees(r.controller_offset[j]):+.1f}"
                + "".join(f" {c:+g} q{k + 1}" for k, c in enumerate(r.controller_coupling[j])
                          if c),
                k,
            )
        console.print(table)
        L = r.characteristic_length
        print_wrapped(console,
                      f"characteristic length: {'not given' if L is None else f'{L:.3f} m'}")
        for zone in r.zones:
            ranges = ", ".join(
                f"q{j + 1} {np.degrees(a):.0f}..{np.degrees(b):.0f} deg"
                for j, (a, b) in zone.ranges.items()
            )
            print_wrapped(console, f"{zone.name}: {ranges}")
        # the robot file's own text: plain (never read as markup), wrapped under its label
        if r.notes:
            print_wrapped(console, f"note: {r.notes}")
        for key, text in r.sources.items():
            print_wrapped(console, f"source {key}: {text}")

