"""``campaign stiffness``: J, K_C, K_X and the deflection at one pose."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING

import typer
from rich.console import Console

from campaign.cli.terminal import print_wrapped
from campaign.numbers_text import matrix_lines, vector_text
from campaign.options import TOOL_RPY_HELP, TOOL_XYZ_HELP, numbers_option

if TYPE_CHECKING:
    import numpy as np


def _matrix(console: Console, title: str, M: np.ndarray, unit: str) -> None:
    console.print(f"[bold]{title}[/bold] ({unit})")
    for line in matrix_lines(M):
        console.print(line, markup=False, highlight=False)


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
        import numpy as np

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
    import numpy as np

    from analysis.report.formatting import k_kNm

    qr, k, w = np.array(res.q_rad), np.array(res.joint_stiffness_Nm_per_rad), \
        np.array(res.wrench_N_Nm)
    lin, exact = np.array(res.deflection_m_rad), np.array(res.deflection_nonlinear_m_rad)
    console = Console()
    print_wrapped(console, f"{res.robot}  q = {vector_text(np.degrees(qr), 6, zeros=False)} "
                  "deg (model convention)")
    print_wrapped(console, f"tool: {res.tool_text}")
    print_wrapped(console, f"k = [{', '.join(k_kNm(v) for v in k)}] kN m/rad "
                  f"({res.joint_stiffness_source})")
    print_wrapped(console, f"w = {vector_text(w[:3], 6, False)} N, "
                  f"{vector_text(w[3:], 6, False)} N m at P, base frame ({res.wrench_source})")
    _matrix(console, "J", np.array(res.J_m_rad_per_rad), "rows 1-3 m/rad, rows 4-6 rad/rad")
    _matrix(console, "K_C", np.array(res.K_C_Nm_per_rad) / 1e3, "kN m/rad")
    if res.K_X is None:
        print_wrapped(console, f"K_X (with and without K_C): undefined: {res.undefined['K_X']}")
    else:
        _matrix(console, "K_X with K_C", np.array(res.K_X), "N/m, N/rad, N, N m/rad blocks")
        _matrix(console, "K_X without K_C", np.array(res.K_X_without_K_C), "same units")
    console.print("[bold]deflection of P[/bold] (mm, mrad)")
    for label, d in (("with K_C", lin),
                     ("without K_C", np.array(res.deflection_without_K_C_m_rad)),
                     ("nonlinear equilibrium", exact)):
        print_wrapped(console, f"  {label:22s} dp = {vector_text(1e3 * d[:3])} mm, "
                      f"dr = {vector_text(1e3 * d[3:])} mrad")
    if res.uncertainty is not None:
        _present_intervals(console, res.uncertainty)


def _present_intervals(console: Console, u: dict) -> None:
    """The 95 % intervals of an identified model (delta method)."""
    import numpy as np

    lo = np.array(u["deflection_nonlinear_lo95_m_rad"])
    hi = np.array(u["deflection_nonlinear_hi95_m_rad"])
    console.print("[bold]95 % intervals[/bold] (identified model, delta method)")
    print_wrapped(console, f"  dp from {vector_text(1e3 * lo[:3])} to "
                  f"{vector_text(1e3 * hi[:3])} mm")
    print_wrapped(console, f"  dr from {vector_text(1e3 * lo[3:])} to "
                  f"{vector_text(1e3 * hi[3:])} mrad")
    half = 1.96 * np.array(u["K_X_diag_se"])
    print_wrapped(console, f"  diag(K_X) +- {vector_text(half[:3])} N/m, "
                  f"{vector_text(half[3:])} N m/rad")
