"""``campaign stiffness``: J, K_C, K_X and the deflection at one pose."""

from __future__ import annotations

import json

import numpy as np
import typer
from rich.console import Console

from analysis.errors import InputError, SingularPoseError
from campaign.cli_common import print_wrapped
from campaign.options import (
    TOOL_RPY_HELP,
    TOOL_XYZ_HELP,
    joint_angles_option,
    robot_and_tool,
    stiffness_option,
    wrench_option,
)


def matrix_lines(M: np.ndarray, digits: int = 5) -> list[str]:
    """Rows of ``M`` with ``digits`` significant digits, in columns wide enough for every entry.

    Round-off (below 1e-9 of the largest entry) is shown as 0, never '-0'; a
    matrix whose entries span beyond 1e-3..1e5 is shown in one exponent style.
    """
    from analysis.report.formatting import clean, sig

    a = clean(M)
    big = np.abs(a[a != 0])
    if big.size and (big.max() >= 1e5 or big.min() < 1e-3):
        def cell(v):
            return "0" if v == 0 else f"{v:.{digits - 1}e}"
    else:
        def cell(v):
            return sig(v, digits)
    cells = [[cell(v) for v in row] for row in a]
    width = max(len(c) for row in cells for c in row)
    return ["  " + " ".join(f"{c:>{width}}" for c in row) for row in cells]


def vector_text(values, digits: int = 4, zeros: bool = True) -> str:
    """``[a, b, c]`` with ``digits`` significant digits and round-off shown as 0.

    ``zeros`` keeps trailing zeros (``4.000``: a measured-looking value); without,
    ``30`` rather than ``30.000`` (typed inputs: angles, wrench).
    """
    from analysis.report.formatting import clean, eng, sig

    fmt = eng if zeros else sig
    return "[" + ", ".join(fmt(float(v), digits) for v in clean(values)) + "]"


def _matrix(console: Console, title: str, M: np.ndarray, unit: str) -> None:
    console.print(f"[bold]{title}[/bold] ({unit})")
    for line in matrix_lines(M):
        console.print(line, markup=False, highlight=False)


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
        "deflection_nonlinear_sd_m_rad": pred.sd.tolist(),
        "deflection_nonlinear_lo95_m_rad": lo.tolist(),
        "deflection_nonlinear_hi95_m_rad": hi.tolist(),
        "K_X_diag_se": se.tolist(),
        "K_X_diag_lo95": (K_X - Z95 * se).tolist(),
        "K_X_diag_hi95": (K_X + Z95 * se).tolist(),
        "method": "covariance of the identified compliances (model file [identification]) "
                  "propagated by the delta method: d(dq)/dx_j = (K_theta - K_C)^-1 e_j "
                  "k_j^2 dq_j at the loaded pose (exact for the linear model without K_C); "
                  "K_X is linear in k, cov(k) from cov(x) by the delta method",
    }


#: what the default wrench is, said wherever it is used (campaign stiffness, campaign maps)
WORST_CASE_TEXT = ("default: the paper's worst case, 2200 N and 400 N m along every base "
                   "axis; --wrench to choose another")


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
        k_source = ("--joint-stiffness" if joint_stiffness else
                    "the identified model's values" if r.compliance_covariance is not None
                    else "the model's nominal values")
        w_source = "--wrench" if wrench else WORST_CASE_TEXT
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
            "joint_stiffness_source": k_source,
            "wrench_N_Nm": w.tolist(),
            "wrench_source": w_source,
            "J_m_rad_per_rad": J.tolist(),
            "K_C_Nm_per_rad": K_C.tolist(),
            "K_X": None if K_X is None else K_X.tolist(),
            "K_X_without_K_C": None if K_X0 is None else K_X0.tolist(),
            "undefined": undefined,
            "deflection_m_rad": lin.tolist(),
            "deflection_without_K_C_m_rad": deflection(J, k, w).tolist(),
            "deflection_nonlinear_m_rad": exact.tolist(),
            "units": {
                "J_m_rad_per_rad": "rows 1-3 m/rad, rows 4-6 rad/rad; base axes at P",
                "K_C_Nm_per_rad": "N m/rad",
                "K_X": "N/m | N/rad ; N | N m/rad blocks, base frame at P (as results.json)",
                "deflection_*_m_rad": "[dx, dy, dz] m, [rx, ry, rz] rad (small rotation "
                                      "vector)",
            },
        }
        cov_x = None if joint_stiffness is not None else r.compliance_covariance
        if cov_x is not None:
            result["uncertainty"] = _intervals(r, qr, k, w, J, cov_x)
        if as_json:
            typer.echo(json.dumps(result, indent=2))
            return
        from analysis.report.formatting import k_kNm

        console = Console()
        print_wrapped(console, f"{r.name}  q = {vector_text(np.degrees(qr), 6, zeros=False)} "
                      "deg (model convention)")
        print_wrapped(console, f"tool: {tool.text()}")
        print_wrapped(console, f"k = [{', '.join(k_kNm(v) for v in k)}] kN m/rad ({k_source})")
        print_wrapped(console, f"w = {vector_text(w[:3], 6, False)} N, "
                      f"{vector_text(w[3:], 6, False)} N m at P, base frame ({w_source})")
        _matrix(console, "J", J, "rows 1-3 m/rad, rows 4-6 rad/rad")
        _matrix(console, "K_C", K_C / 1e3, "kN m/rad")
        if K_X is None:
            print_wrapped(console, f"K_X (with and without K_C): undefined: {undefined['K_X']}")
        else:
            _matrix(console, "K_X with K_C", K_X, "N/m, N/rad, N, N m/rad blocks")
            _matrix(console, "K_X without K_C", K_X0, "same units")
        console.print("[bold]deflection of P[/bold] (mm, mrad)")
        for label, d in (("with K_C", lin), ("without K_C", deflection(J, k, w)),
                         ("nonlinear equilibrium", exact)):
            print_wrapped(console, f"  {label:22s} dp = {vector_text(1e3 * d[:3])} mm, "
                          f"dr = {vector_text(1e3 * d[3:])} mrad")
        if cov_x is not None:
            u = result["uncertainty"]
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
