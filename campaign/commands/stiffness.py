"""``campaign stiffness``: J, K_C, K_X and the deflection at one pose."""

from __future__ import annotations

import json

import numpy as np
import typer
from rich.console import Console

from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option


def _matrix(console: Console, title: str, M: np.ndarray, unit: str) -> None:
    console.print(f"[bold]{title}[/bold] ({unit})")
    for row in M:
        console.print("  " + " ".join(f"{v: .4e}" for v in row))


def register(app: typer.Typer) -> None:
    @app.command("stiffness")
    def stiffness(
        robot: str = typer.Option(..., help="Built-in name, robot file or URDF."),
        q: str = typer.Option(..., help="Joint angles in degrees, comma-separated."),
        tip: str = typer.Option(None, help="Tool frame of a URDF."),
        tool_xyz_mm: str = typer.Option(None, help=TOOL_XYZ_HELP),
        tool_rpy_deg: str = typer.Option(None, help=TOOL_RPY_HELP),
        controller: bool = typer.Option(
            False, "--controller-angles", help="--q is in the teach-pendant convention."
        ),
        joint_stiffness: str = typer.Option(
            None, help="k1,...,k6 in N m/rad (default: the model's nominal values)."
        ),
        wrench: str = typer.Option(
            None, help="fx,fy,fz (N), mx,my,mz (N m) at P, base frame "
            "(default: the paper's worst case 2200 N, 400 N m on each axis)."
        ),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units)."),
        ignore_limits: bool = typer.Option(
            False, "--ignore-limits", help="Accept joint angles outside the robot's limits."),
    ) -> None:
        """Kinematic Jacobian, K_C (eq. 8), K_X with and without K_C (eqs. 6, 12), deflection."""
        from campaign.jobs.stiffness import StiffnessOptions, run

        res = run(StiffnessOptions(
            robot=robot, q_rad=np.radians(numbers_option(q, "--q")).tolist(), tip=tip,
            tool_xyz_mm=numbers_option(tool_xyz_mm, "--tool-xyz-mm"),
            tool_rpy_deg=numbers_option(tool_rpy_deg, "--tool-rpy-deg"),
            controller_angles=controller,
            joint_stiffness_Nm_per_rad=numbers_option(joint_stiffness, "--joint-stiffness"),
            wrench_N_Nm=numbers_option(wrench, "--wrench"), ignore_limits=ignore_limits))
        if as_json:
            typer.echo(json.dumps(res.to_json(), indent=2))
            return
        _present(res)


def _present(res) -> None:
    """The text summary of a :class:`campaign.jobs.stiffness.StiffnessResult`."""
    qr, k, w = np.array(res.q_rad), res.joint_stiffness_Nm_per_rad, res.wrench_N_Nm
    lin, exact = np.array(res.deflection), np.array(res.deflection_nonlinear)
    console = Console()
    console.print(f"[bold]{res.robot}[/bold]  q = {np.degrees(qr).round(3).tolist()} deg "
                  "(model convention)")
    console.print(f"tool: {res.tool_text}")
    console.print(f"k = {k} N m/rad;  w = {w} N, N m")
    _matrix(console, "J", np.array(res.J), "rows 1-3 m/rad, rows 4-6 rad/rad")
    _matrix(console, "K_C", np.array(res.K_C), "N m/rad")
    if res.K_X is None:
        console.print(f"[bold]K_X[/bold] (with and without K_C): undefined: "
                      f"{res.undefined['K_X']}")
    else:
        _matrix(console, "K_X with K_C", np.array(res.K_X), "N/m, N/rad, N, N m/rad blocks")
        _matrix(console, "K_X without K_C", np.array(res.K_X_without_K_C), "same units")
    console.print("[bold]deflection of P[/bold] (mm, mrad)")
    for label, d in (("with K_C", lin), ("without K_C", np.array(res.deflection_without_K_C)),
                     ("nonlinear equilibrium", exact)):
        console.print(f"  {label:22s} dp = {np.round(1e3 * d[:3], 4).tolist()} mm, "
                      f"dr = {np.round(1e3 * d[3:], 4).tolist()} mrad")
    if res.uncertainty is not None:
        u = res.uncertainty
        lo = np.array(u["deflection_nonlinear_lo95"])
        hi = np.array(u["deflection_nonlinear_hi95"])
        console.print("[bold]95 % intervals[/bold] (identified model, delta method)")
        console.print(f"  dp from {np.round(1e3 * lo[:3], 4).tolist()} to "
                      f"{np.round(1e3 * hi[:3], 4).tolist()} mm")
        console.print(f"  dr from {np.round(1e3 * lo[3:], 4).tolist()} to "
                      f"{np.round(1e3 * hi[3:], 4).tolist()} mrad")
        half = np.round(1.96 * np.array(u["K_X_diag_se"]), 1).tolist()
        console.print(f"  diag(K_X) +- {half} (SI)")
