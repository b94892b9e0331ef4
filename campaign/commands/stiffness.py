"""``campaign stiffness``: J, K_C, K_X and the deflection at one pose."""

from __future__ import annotations

import json

import numpy as np
import typer
from rich.console import Console

from analysis.errors import InputError, SingularPoseError
from campaign.options import (
    TOOL_RPY_HELP,
    TOOL_XYZ_HELP,
    joint_angles_option,
    robot_and_tool,
    stiffness_option,
    wrench_option,
)


def _matrix(console: Console, title: str, M: np.ndarray, unit: str) -> None:
    console.print(f"[bold]{title}[/bold] ({unit})")
    for row in M:
        console.print("  " + " ".join(f"{v: .4e}" for v in row))


def _intervals(r, q, k, w, J, cov_x) -> dict:
    """95 % intervals of the nonlinear deflection and of diag(K_X) from the model's covariance."""
    from analysis.kinetostatics.stiffness import (
        cartesian_stiffness,
        complementary_stiffness_from_state,
    )
    from analysis.kinetostatics.uncertainty import (
        Z95,
        cartesian_stiffness_se,
        predict_deflection,
        stiffness_covariance,
    )
    from analysis.model.kinematics import chain_state

    pred = predict_deflection(r, q, k, w, cov_x)
    lo, hi = pred.bounds(Z95)
    se = np.diagonal(cartesian_stiffness_se(J, stiffness_covariance(k, cov_x)))
    K_X = np.diagonal(cartesian_stiffness(J, k, complementary_stiffness_from_state(
        chain_state(r, q), w)))
    return {
        "confidence": 0.95,
        "deflection_nonlinear_sd": pred.sd.tolist(),
        "deflection_nonlinear_lo95": lo.tolist(),
        "deflection_nonlinear_hi95": hi.tolist(),
        "K_X_diag_se": se.tolist(),
        "K_X_diag_lo95": (K_X - Z95 * se).tolist(),
        "K_X_diag_hi95": (K_X + Z95 * se).tolist(),
        "method": "covariance of the identified compliances (model file [identification]) "
                  "propagated by the delta method: d(dq)/dx_j = (K_theta - K_C)^-1 e_j "
                  "k_j^2 dq_j at the loaded pose (exact for the linear model without K_C); "
                  "K_X is linear in k, cov(k) from cov(x) by the delta method",
    }


def check_limits(robot, q: np.ndarray, controller: bool) -> None:
    """Refuse joint angles (rad, model convention) outside the limits, naming the joint."""
    out = (q < robot.lower - 1e-12) | (q > robot.upper + 1e-12)
    if not np.any(out):
        return
    j = int(np.flatnonzero(out)[0])
    typed = (f" (typed {np.degrees(robot.to_controller(q)[j]):.4g} deg in the pendant "
             "convention)") if controller else ""
    raise InputError(
        f"q{j + 1} = {np.degrees(q[j]):.4g} deg{typed} is outside the joint limits "
        f"[{np.degrees(robot.lower[j]):g}, {np.degrees(robot.upper[j]):g}] deg of "
        f"{robot.name} (model convention); add --ignore-limits to compute anyway",
        where="--q")


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
        # analysis.* pulls in pinocchio: imported when the command runs, not at start-up
        from analysis.kinetostatics.equilibrium import solve_deflection
        from analysis.kinetostatics.maps import WORST_CASE_WRENCH
        from analysis.kinetostatics.stiffness import (
            cartesian_stiffness,
            complementary_stiffness_from_state,
            deflection,
        )
        from analysis.kinetostatics.validity import check_small_displacement
        from analysis.model.kinematics import chain_state, jacobian_from_state, pose_difference

        r, tool = robot_and_tool(robot, tip, tool_xyz_mm, tool_rpy_deg)
        qr = r.check_q(joint_angles_option(r, q, controller), where="--q")
        if not ignore_limits:
            check_limits(r, qr, controller)
        k = stiffness_option(r, joint_stiffness)
        w = wrench_option(wrench, WORST_CASE_WRENCH)
        state = chain_state(r, qr)
        J = jacobian_from_state(state)
        K_C = complementary_stiffness_from_state(state, w)
        # K_X needs J^-1; at a singular pose (e.g. the KUKA home pose, A5 = 0) J, K_C and
        # the deflections are still defined and are reported, K_X is marked undefined.
        undefined: dict[str, str] = {}
        K_X = K_X0 = None
        try:
            K_X = cartesian_stiffness(J, k, K_C)
            K_X0 = cartesian_stiffness(J, k)
        except SingularPoseError:
            sv = np.linalg.svd(J, compute_uv=False)
            reason = (f"J is singular at this pose (smallest singular value {sv[-1]:.3g}, "
                      f"largest {sv[0]:.3g}): K_X = J^-T (K_theta - K_C) J^-1 needs J^-1; "
                      "the compliance J (K_theta - K_C)^-1 J^T and the deflections are defined")
            undefined = {"K_X": reason, "K_X_without_K_C": reason}
        lin = deflection(J, k, w, K_C)
        dq = solve_deflection(r, qr, k, w)
        exact = pose_difference(state.tip, chain_state(r, qr + dq).tip)
        check_small_displacement(r, dq, exact)
        result = {
            "robot": r.name,
            "tool": tool.describe(),
            "q_rad": qr.tolist(),
            "joint_stiffness_Nm_per_rad": k.tolist(),
            "wrench_N_Nm": w.tolist(),
            "J": J.tolist(),
            "K_C": K_C.tolist(),
            "K_X": None if K_X is None else K_X.tolist(),
            "K_X_without_K_C": None if K_X0 is None else K_X0.tolist(),
            "undefined": undefined,
            "deflection": lin.tolist(),
            "deflection_without_K_C": deflection(J, k, w).tolist(),
            "deflection_nonlinear": exact.tolist(),
            "units": {
                "J": "rows 1-3 m/rad, rows 4-6 rad/rad; base axes at P",
                "K_C": "N m/rad",
                "K_X": "N/m | N/rad ; N | N m/rad blocks, base frame at P",
                "deflection": "[dx, dy, dz] m, [rx, ry, rz] rad (small rotation vector)",
            },
        }
        cov_x = None if joint_stiffness is not None else r.compliance_covariance
        if cov_x is not None:
            result["uncertainty"] = _intervals(r, qr, k, w, J, cov_x)
        if as_json:
            typer.echo(json.dumps(result, indent=2))
            return
        console = Console()
        console.print(f"[bold]{r.name}[/bold]  q = {np.degrees(qr).round(3).tolist()} deg "
                      "(model convention)")
        console.print(f"tool: {tool.text()}")
        console.print(f"k = {k.tolist()} N m/rad;  w = {w.tolist()} N, N m")
        _matrix(console, "J", J, "rows 1-3 m/rad, rows 4-6 rad/rad")
        _matrix(console, "K_C", K_C, "N m/rad")
        if K_X is None:
            console.print(f"[bold]K_X[/bold] (with and without K_C): undefined: "
                          f"{undefined['K_X']}")
        else:
            _matrix(console, "K_X with K_C", K_X, "N/m, N/rad, N, N m/rad blocks")
            _matrix(console, "K_X without K_C", K_X0, "same units")
        console.print("[bold]deflection of P[/bold] (mm, mrad)")
        for label, d in (("with K_C", lin), ("without K_C", deflection(J, k, w)),
                         ("nonlinear equilibrium", exact)):
            console.print(f"  {label:22s} dp = {np.round(1e3 * d[:3], 4).tolist()} mm, "
                          f"dr = {np.round(1e3 * d[3:], 4).tolist()} mrad")
        if cov_x is not None:
            u = result["uncertainty"]
            lo = np.array(u["deflection_nonlinear_lo95"])
            hi = np.array(u["deflection_nonlinear_hi95"])
            console.print("[bold]95 % intervals[/bold] (identified model, delta method)")
            console.print(f"  dp from {np.round(1e3 * lo[:3], 4).tolist()} to "
                          f"{np.round(1e3 * hi[:3], 4).tolist()} mm")
            console.print(f"  dr from {np.round(1e3 * lo[3:], 4).tolist()} to "
                          f"{np.round(1e3 * hi[3:], 4).tolist()} mrad")
            half = np.round(1.96 * np.array(u["K_X_diag_se"]), 1).tolist()
            console.print(f"  diag(K_X) +- {half} (SI)")
