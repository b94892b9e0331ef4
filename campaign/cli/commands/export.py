"""``campaign export``: the robot as a MuJoCo MJCF, URDF or SDFormat file with its joint springs."""

from __future__ import annotations

from pathlib import Path

import typer

from campaign.cli.terminal import PANEL_OUTPUT, PANEL_ROBOT, SimFormat, echo, print_json
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option


def register(app: typer.Typer) -> None:
    @app.command("export")
    def export(
        robot: str = typer.Option(..., help="model.toml from campaign analyze, a built-in "
                                  "name, a robot file or a URDF.", rich_help_panel=PANEL_ROBOT),
        fmt: SimFormat = typer.Option(..., "--format", help="mjcf (MuJoCo), urdf (springs in "
                                      "Gazebo's extension) or sdf (SDFormat 1.9).",
                                      rich_help_panel=PANEL_OUTPUT),
        out: Path = typer.Option(..., help="File to write (.xml/.mjcf, .urdf, .sdf).",
                                 rich_help_panel=PANEL_OUTPUT),
        tip: str = typer.Option(None, help="Tool frame of a URDF.", rich_help_panel=PANEL_ROBOT),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP, rich_help_panel=PANEL_ROBOT),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP,
                                         rich_help_panel=PANEL_ROBOT),
        joint_stiffness: str = typer.Option(
            None, help="k1,...,k6 in N m/rad (default: the model's identified or nominal "
            "values).", rich_help_panel=PANEL_ROBOT),
        no_springs: bool = typer.Option(False, "--no-springs", help="Write the kinematic "
                                        "chain alone (a robot without stiffness).",
                                        rich_help_panel=PANEL_ROBOT),
        force: bool = typer.Option(False, "--force", help="Replace an existing --out file.",
                                   rich_help_panel=PANEL_OUTPUT),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units).",
                                     rich_help_panel=PANEL_OUTPUT),
    ) -> None:
        """Write the robot as a simulator file: MJCF, URDF or SDF with its joint springs."""
        from campaign.jobs.export import ExportOptions, run

        result = run(ExportOptions(
            robot=robot, format=fmt, out=out, tip=tip,
            tool_xyz_mm=numbers_option(tool_xyz_mm, "--tool-xyz-mm"),
            tool_rpy_deg=numbers_option(tool_rpy_deg, "--tool-rpy-deg"),
            joint_stiffness_Nm_per_rad=numbers_option(joint_stiffness, "--joint-stiffness"),
            no_springs=no_springs, force=force))
        if as_json:
            print_json(result.to_json())
            return
        echo(f"robot: {result.robot} ({result.source})")
        echo(f"joint stiffness: {result.stiffness_source}")
        for item in result.left_out:
            echo(f"not carried by the file: {item}")
        for item in result.notes:
            echo(f"note: {item}")
        echo(f"wrote {result.file} ({result.format})")
