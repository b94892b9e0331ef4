"""``campaign place``: where to put the workpiece and how to turn the tool so P deflects least.

The options are the fields of :class:`campaign.jobs.place.PlaceOptions` with its
defaults (the web API's too); the job parses them. Heavy modules (numpy maths,
Pinocchio, Dask, matplotlib) are imported inside the command: the CLI's start-up time
is measured.
"""

from __future__ import annotations

from pathlib import Path

import typer

from campaign.cli.terminal import (
    PANEL_OUTPUT,
    PANEL_ROBOT,
    PROGRAM_CHOICES,
    PROGRAM_METAVAR,
    Objective,
    Program,
)
from campaign.jobs.place import DEFAULTS as _D
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP

#: panels of --help (campaign.cli.terminal)
_BOX = "Part path and search box"
_TOOL = "Tool angle"
_FEASIBLE = "Feasibility"
_OBJECTIVE = "Objective"
_DASK = "Dask"
_PROGRAM = "Robot program"
_SIZE = "Size of the search"


def register(app: typer.Typer) -> None:
    @app.command("place")
    def place(
        robot: str = typer.Option(
            ..., help="Built-in name, robot file or URDF.", rich_help_panel=PANEL_ROBOT),
        path: Path = typer.Option(
            ..., "--path", help="Part path CSV (workpiece frame).", rich_help_panel=_BOX),
        out: Path = typer.Option(..., help="Output directory.", rich_help_panel=PANEL_OUTPUT),
        tip: str = typer.Option(
            _D["tip"], help="Tool frame of a URDF.", rich_help_panel=PANEL_ROBOT),
        tool_xyz_mm: str = typer.Option(
            _D["tool_xyz_mm"], help=TOOL_XYZ_HELP, rich_help_panel=PANEL_ROBOT),
        tool_rpy_deg: str = typer.Option(
            _D["tool_rpy_deg"], help=TOOL_RPY_HELP, rich_help_panel=PANEL_ROBOT),
        x_mm: str = typer.Option(
            ..., help="Workpiece origin x range A..B (mm, base frame).", rich_help_panel=_BOX),
        y_mm: str = typer.Option(
            ..., help="Workpiece origin y range A..B (mm).", rich_help_panel=_BOX),
        z_mm: str = typer.Option(
            ..., help="Workpiece origin z range A..B (mm).", rich_help_panel=_BOX),
        yaw_deg: str = typer.Option(
            _D["yaw_deg"], help="Workpiece yaw about the base z, A..B (deg).",
            rich_help_panel=_BOX),
        x_step_mm: float = typer.Option(
            _D["x_step_mm"], help="Grid step of x (mm).", rich_help_panel=_BOX),
        y_step_mm: float = typer.Option(
            _D["y_step_mm"], help="Grid step of y (mm).", rich_help_panel=_BOX),
        z_step_mm: float = typer.Option(
            _D["z_step_mm"], help="Grid step of z (mm).", rich_help_panel=_BOX),
        yaw_step_deg: float = typer.Option(
            _D["yaw_step_deg"], help="Grid step of the yaw (deg).", rich_help_panel=_BOX),
        tool_angle_deg: str = typer.Option(
            _D["tool_angle_deg"], help="Free angle about the tool axis, A..B (deg); a full turn "
            "leaves out its duplicate end.", rich_help_panel=_TOOL),
        tool_angle_step_deg: float = typer.Option(
            _D["tool_angle_step_deg"], help="Step of the tool angle (deg).", rich_help_panel=_TOOL),
        max_joint_step_deg: float = typer.Option(
            _D["max_joint_step_deg"], help="Largest motion of any joint between neighbouring "
            "points (deg).", rich_help_panel=_FEASIBLE),
        config: str = typer.Option(
            _D["config"], help="Configuration flags shoulder,elbow,wrist (+1/-1), or 'any' to try "
            "all eight; the same flags hold along the whole path.", rich_help_panel=_FEASIBLE),
        limit_margin_deg: float = typer.Option(
            _D["limit_margin_deg"], help="Margin inside the joint limits (deg).",
            rich_help_panel=_FEASIBLE),
        min_inv_kappa: float = typer.Option(
            _D["min_inv_kappa"], help="Smallest 1/kappa_F of J_N accepted (distance to "
            "singularity).", rich_help_panel=_FEASIBLE),
        length: float = typer.Option(
            _D["length"], help="Characteristic length L of J_N (m); default the model's, else "
            "computed.", rich_help_panel=_FEASIBLE),
        keep_out_mm: str = typer.Option(
            _D["keep_out_mm"], help="Keep-out box x0..x1,y0..y1,z0..z1 (mm, base frame) that no "
            "joint origin may enter (e.g. the table below the part).", rich_help_panel=_FEASIBLE),
        objective: Objective = typer.Option(
            _D["objective"], help="max: largest |dp| along the path; rms: root mean square |dp|; "
            "compliance: largest worst-direction translational compliance.",
            rich_help_panel=_OBJECTIVE),
        upper_bound: bool = typer.Option(
            _D["upper_bound"], "--upper-bound", help="Minimise the 95 % upper bound of |dp| "
            "(needs the stiffness covariance of an identified model.toml).",
            rich_help_panel=_OBJECTIVE),
        wrench: str = typer.Option(
            _D["wrench"], help="Constant process wrench fx,fy,fz (N), mx,my,mz (N m) at P, tool "
            "frame; overrides the path file's wrench columns.", rich_help_panel=PANEL_ROBOT),
        joint_stiffness: str = typer.Option(
            _D["joint_stiffness"], help="k1,...,k6 (N m/rad).", rich_help_panel=PANEL_ROBOT),
        scheduler: str = typer.Option(
            _D["scheduler"], help="Address of an existing Dask scheduler, tcp://HOST:PORT.",
            rich_help_panel=_DASK),
        workers: int = typer.Option(
            _D["workers"], help="Worker processes of the local Dask cluster (default: the CPU "
            "count); 0 runs in this process without Dask.", rich_help_panel=_DASK),
        chunk: int = typer.Option(
            _D["chunk"], help="Placements per task (default: automatic).", rich_help_panel=_DASK),
        max_evaluations: float = typer.Option(
            _D["max_evaluations"], help="Largest search allowed, in evaluations (placement x "
            "point x tool angle x configuration); default 1e8, no limit with --scheduler.",
            rich_help_panel=_SIZE),
        max_memory_gib: float = typer.Option(
            _D["max_memory_gib"], help="Largest memory for the per-placement results (GiB).",
            rich_help_panel=_SIZE),
        runner_ups: int = typer.Option(
            _D["runner_ups"], help="Runner-up placements listed.", rich_help_panel=PANEL_OUTPUT),
        program: Program = typer.Option(
            _D["program"], metavar=PROGRAM_METAVAR, help="Robot program of the path, one of: "
            + PROGRAM_CHOICES + ".", rich_help_panel=_PROGRAM),
        force: bool = typer.Option(
            _D["force"], "--force", help="Write into a non-empty --out (its files are replaced).",
            rich_help_panel=PANEL_OUTPUT),
    ) -> None:
        """Search the workpiece placement and tool angles that minimise P's deflection."""
        options = dict(locals())  # the option names are PlaceOptions' fields
        from rich.console import Console

        from campaign.jobs.place import PlaceOptions, run

        run(PlaceOptions(**options), console=Console())
