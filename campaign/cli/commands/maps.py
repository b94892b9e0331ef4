"""``campaign maps``: 1/kappa_F, v_p and v_r over the (theta_2, theta_3) grid and workspace."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.console import Console

from campaign.cli.terminal import (
    PANEL_OUTPUT,
    PANEL_ROBOT,
    TableFormat,
    print_json,
    print_wrapped,
    stage,
)
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option

#: panel of --help (campaign.cli.terminal)
_GRID = "Map grid"


def register(app: typer.Typer) -> None:
    @app.command("maps")
    def maps(
        robot: str = typer.Option(..., help="Built-in name, robot file or URDF.",
            rich_help_panel=PANEL_ROBOT),
        out: Path = typer.Option(..., help="Output directory.", rich_help_panel=PANEL_OUTPUT),
        tip: str = typer.Option(None, help="Tool frame of a URDF.", rich_help_panel=PANEL_ROBOT),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP, rich_help_panel=PANEL_ROBOT),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP, rich_help_panel=PANEL_ROBOT),
        step: float = typer.Option(1.0, help="Grid step (deg).", rich_help_panel=_GRID),
        fixed: str = typer.Option(
            None, help="Other joints q1..q6 in degrees (model convention); entries 2 and 3 "
            "are ignored. Default: theta1 = 0, theta4..6 = 45 deg as in the paper.",
            rich_help_panel=_GRID
        ),
        joint_stiffness: str = typer.Option(None, help="k1,...,k6 (N m/rad).",
            rich_help_panel=PANEL_ROBOT),
        wrench: str = typer.Option(
            None, help="fx,fy,fz (N), mx,my,mz (N m); default the paper's worst case.",
            rich_help_panel=PANEL_ROBOT
        ),
        length: float = typer.Option(
            None, help="Characteristic length L (m); default the model's, else computed.",
            rich_help_panel=_GRID
        ),
        fmt: TableFormat = typer.Option("parquet", "--format", help="Map table format.",
            rich_help_panel=PANEL_OUTPUT),
        upper_bound: bool = typer.Option(
            False, "--deflection-upper-bound", help="Also map the 95 % upper bound of the "
            "deflection |dp| from the identified model's covariance (model.toml).",
            rich_help_panel=_GRID),
        force: bool = typer.Option(False, "--force", help="Write into a non-empty --out "
                                   "(its map files are replaced).", rich_help_panel=PANEL_OUTPUT),
        as_json: bool = typer.Option(False, "--json", help="Print map_summary.json (SI "
                                     "units) instead of the text summary.",
            rich_help_panel=PANEL_OUTPUT),
    ) -> None:
        """Maps like the paper's Figs. 3 and 5: data table and PNG plots."""
        import numpy as np

        from campaign.jobs.maps import MapsOptions, run

        def rad(text: str | None, where: str) -> list[float] | None:
            deg = numbers_option(text, where)
            return None if deg is None else np.radians(deg).tolist()

        si = numbers_option

        console = Console(stderr=as_json)
        result = run(MapsOptions(
            robot, out, tip, si(tool_xyz_mm, "--tool-xyz-mm"),
            si(tool_rpy_deg, "--tool-rpy-deg"), float(np.radians(step)), rad(fixed, "--fixed"),
            si(joint_stiffness, "--joint-stiffness"), si(wrench, "--wrench"), length, fmt,
            upper_bound, force), stage=stage, note=lambda text: print_wrapped(console, text))
        s = result.summary
        if as_json:
            print_json(result.to_json())
            return
        print_wrapped(console,
            f"{s['nodes']} poses, {s['singular_nodes']} singular; "
            f"max v_p = {s['max_v_p']:.4f}, max v_r = {s['max_v_r_deg']:.4f} deg, "
            f"max 1/kappa_F = {s['max_inv_kappa_F']:.3f}"
        )
        if result.bound_at_deg is not None:
            t2, t3 = result.bound_at_deg
            print_wrapped(console, f"95 % upper bound of |dp|: at most "
                          f"{s['max_deflection_upper95_mm']:.4g} mm over the grid (at "
                          f"theta2 = {t2:.4g} deg, theta3 = {t3:.4g} deg); column "
                          "deflection_upper95_mm and deflection_upper95_*.png")
        print_wrapped(console, f"wrote {result.data_file} and PNG plots to {out}/")
