"""``campaign maps``: 1/kappa_F, v_p and v_r over the (theta_2, theta_3) grid and workspace."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer
from rich.console import Console

from campaign.cli_common import TableFormat, print_json, stage
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option


def register(app: typer.Typer) -> None:
    @app.command("maps")
    def maps(
        robot: str = typer.Option(..., help="Built-in name, robot file or URDF."),
        out: Path = typer.Option(..., help="Output directory."),
        tip: str = typer.Option(None, help="Tool frame of a URDF."),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP),
        step: float = typer.Option(1.0, help="Grid step (deg)."),
        fixed: str = typer.Option(
            None, help="Other joints q1..q6 in degrees (model convention); entries 2 and 3 "
            "are ignored. Default: theta1 = 0, theta4..6 = 45 deg as in the paper."
        ),
        joint_stiffness: str = typer.Option(None, help="k1,...,k6 (N m/rad)."),
        wrench: str = typer.Option(
            None, help="fx,fy,fz (N), mx,my,mz (N m); default the paper's worst case."
        ),
        length: float = typer.Option(
            None, help="Characteristic length L (m); default the model's, else computed."
        ),
        fmt: TableFormat = typer.Option("parquet", "--format", help="Map table format."),
        upper_bound: bool = typer.Option(
            False, "--deflection-upper-bound", help="Also map the 95 % upper bound of the "
            "deflection |dp| from the identified model's covariance (model.toml)."),
        force: bool = typer.Option(False, "--force", help="Write into a non-empty --out "
                                   "(its map files are replaced)."),
        as_json: bool = typer.Option(False, "--json", help="Print map_summary.json (SI "
                                     "units) instead of the text summary."),
    ) -> None:
        """Maps like the paper's Figs. 3 and 5: data table and PNG plots."""
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
            upper_bound, force), stage=stage, note=console.print)
        s = result.summary
        if as_json:
            print_json(result.to_json())
            return
        console.print(
            f"{s['nodes']} poses, {s['singular_nodes']} singular; "
            f"max v_p = {s['max_v_p']:.4f}, max v_r = {s['max_v_r_deg']:.4f} deg, "
            f"max 1/kappa_F = {s['max_inv_kappa_F']:.3f}"
        )
        console.print(f"wrote {result.data_file} and PNG plots to {out}/")
