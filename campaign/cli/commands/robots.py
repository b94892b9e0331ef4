"""``campaign robots``: list the built-in models, or show one model's table."""

from __future__ import annotations

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from analysis.report.formatting import k_kNm
from campaign.cli.terminal import print_json, print_wrapped


def _listing(console: Console, robots: list[dict]) -> None:
    table = Table(title="Built-in robot models")
    for col in ("name", "model", "convention", "nominal stiffness", "zones"):
        table.add_column(col)
    for r in robots:
        table.add_row(r["key"], escape(r["name"]), r["convention"],
                      "yes" if r["nominal_stiffness_Nm_per_rad"] is not None else "no",
                      str(len(r["zones"])))
    console.print(table)


def _model(console: Console, r: dict) -> None:
    import numpy as np

    table = Table(title=escape(f"{r['name']} ({r['source_file']})"),
                  caption="angles in the model convention; pendant angle = sign q + "
                  "offset (+ coupling)")
    for col in ("joint", "lower (deg)", "upper (deg)", "pendant (deg)",
                "nominal k (kN m/rad)"):
        table.add_column(col, justify="right")
    lower, upper = np.degrees(r["lower_rad"]), np.degrees(r["upper_rad"])
    offset, nominal = np.degrees(r["controller_offset_rad"]), r["nominal_stiffness_Nm_per_rad"]
    for j in range(r["joints"]):
        k = "-" if nominal is None else k_kNm(nominal[j])
        table.add_row(
            str(j + 1), f"{lower[j]:.1f}", f"{upper[j]:.1f}",
            f"{r['controller_sign'][j]:+d} q {offset[j]:+.1f}"
            + "".join(f" {c:+g} q{i + 1}" for i, c in enumerate(r["controller_coupling"][j])
                      if c),
            k,
        )
    console.print(table)
    L = r["characteristic_length_m"]
    print_wrapped(console,
                  f"characteristic length: {'not given' if L is None else f'{L:.3f} m'}")
    for zone in r["zones"]:
        ranges = ", ".join(f"{j} {np.degrees(a):.0f}..{np.degrees(b):.0f} deg"
                           for j, (a, b) in zone["ranges_rad"].items())
        print_wrapped(console, f"{zone['name']}: {ranges}")
    # the robot file's own text: plain (never read as markup), wrapped under its label
    if r["notes"]:
        print_wrapped(console, f"note: {r['notes']}")
    for key, text in r["sources"].items():
        print_wrapped(console, f"source {key}: {text}")


def register(app: typer.Typer) -> None:
    @app.command("robots")
    def robots(
        name: str = typer.Argument(None, help="Show this model (built-in name or file)."),
        tip: str = typer.Option(None, help="Tool frame of a URDF."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units, rad)."),
    ) -> None:
        """List built-in robot models, or show one model's joints, limits and sources."""
        from campaign.jobs.robots import RobotsOptions, run

        result = run(RobotsOptions(name, tip))
        if as_json:
            print_json(result.to_json())
            return
        console = Console(width=min(Console().width, 80))  # fits an 80-column terminal
        if result.single:
            _model(console, result.robots[0])
        else:
            _listing(console, result.robots)
