"""``campaign maps``: 1/kappa_F, v_p and v_r over the (theta_2, theta_3) grid and workspace."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import typer
from rich.console import Console

from analysis.errors import InputError
from campaign.cli_common import (
    PANEL_OUTPUT,
    PANEL_ROBOT,
    TableFormat,
    output_dir,
    print_json,
    print_wrapped,
    stage,
)
from campaign.options import (
    TOOL_RPY_HELP,
    TOOL_XYZ_HELP,
    parse_floats,
    robot_option,
    stiffness_option,
    wrench_option,
)

#: what --deflection-upper-bound maps, said when it is used
BOUND_TEXT = ("deflection upper bound: |dp| + 1.96 sd(|dp|), the 95 % upper bound of |dp| "
              "(linear model with K_C, the maps' model), sd from the identified compliances' "
              "covariance (the robot file's [identification]) by the delta method along dp")

#: panel of --help (campaign.cli_common)
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
        # pinocchio, scipy, pandas and matplotlib: imported when the command runs
        from analysis.kinetostatics.dexterity import characteristic_length
        from analysis.kinetostatics.map_plots import LABELS, plot_cartesian_map, plot_joint_map
        from analysis.kinetostatics.maps import WORST_CASE_WRENCH, GridSpec, joint_space_map

        console = Console(stderr=as_json)
        fmt = str(fmt)
        r = robot_option(robot, tip, tool_xyz_mm, tool_rpy_deg)
        if step <= 0 or not np.isfinite(step):
            raise InputError("expected a positive step in degrees", where="--step")
        if fmt not in ("parquet", "csv"):
            raise InputError("expected parquet or csv", where="--format")
        k = stiffness_option(r, joint_stiffness)
        w = wrench_option(wrench, WORST_CASE_WRENCH)
        fixed_q = None if fixed is None else np.radians(parse_floats(fixed, "--fixed", r.n))
        if length is not None and not length > 0:
            raise InputError("expected a positive length in m", where="--length")
        how = "given on the command line"
        if length is None and r.characteristic_length is not None:
            length, how = r.characteristic_length, "from the robot model"
        elif length is None:
            with stage("characteristic length"):
                length, _, _ = characteristic_length(r)
            how = "computed (minimum condition number of J_N over posture and L)"
        output_dir(out, force)
        from analysis.report.formatting import k_kNm
        from campaign.commands.stiffness import WORST_CASE_TEXT, vector_text

        w_source = "--wrench" if wrench else WORST_CASE_TEXT
        print_wrapped(console, f"wrench w = {vector_text(w[:3], 6, False)} N, "
                      f"{vector_text(w[3:], 6, False)} N m at P, base frame ({w_source})")
        print_wrapped(console, f"joint stiffness [{', '.join(k_kNm(v) for v in k)}] kN m/rad ("
                      + ("--joint-stiffness" if joint_stiffness else "the robot model's") + ")")
        print_wrapped(console, f"characteristic length L = {length:.4f} m ({how})")
        grid = GridSpec.from_limits(r, np.radians(step), fixed_q)
        with stage(f"map of {r.name} ({step:g} deg grid)"):
            table = joint_space_map(r, grid, k, w, length)
        bound_cols = []
        if upper_bound:
            if r.compliance_covariance is None or joint_stiffness is not None:
                raise InputError("--deflection-upper-bound needs an identified model "
                                 "(model.toml from campaign analyze) and no --joint-stiffness",
                                 where="--deflection-upper-bound")
            from analysis.kinetostatics.uncertainty import linear_deflection_upper_bound

            table["deflection_upper95_mm"] = 1e3 * linear_deflection_upper_bound(
                r, grid.poses(), k, w, r.compliance_covariance).ravel()
            bound_cols = [("deflection_upper95_mm", "deflection_upper95")]
            print_wrapped(console, BOUND_TEXT)
        from analysis.output_files import make_dir, replacing, write_text

        make_dir(out)
        data = out / f"map_joint_space.{fmt}"
        with replacing(data) as tmp:
            if fmt == "parquet":
                table.to_parquet(tmp, index=False)
            else:
                table.to_csv(tmp, index=False)
        zones = [
            (z.name, tuple(np.degrees(z.ranges[1])), tuple(np.degrees(z.ranges[2])))
            for z in r.zones
            if 1 in z.ranges and 2 in z.ranges
        ]
        fixed_deg = np.degrees(grid.fixed)
        others = ", ".join(f"$\\theta_{j + 1}$ = {fixed_deg[j]:g}" for j in range(r.n)
                           if j not in (1, 2))
        from analysis.report.build import wrench_text

        under = f", under {wrench_text(w)}"  # what the v_p, v_r and deflection maps depend on
        with stage("plots"):
            for col, name in (("inv_kappa_F", "inv_kappa_F"), ("v_p", "v_p"),
                              ("v_r_deg", "v_r"), *bound_cols):
                label = LABELS.get(col, "95 % upper bound of |dp| (mm), identified model")
                load = "" if col == "inv_kappa_F" else under.lstrip(", ") + ", "
                plot_joint_map(table, col, out / f"{name}_joint.png",
                               f"{r.name}: {label}\n{load}{others} deg", zones=zones)
                plot_cartesian_map(table, col, out / f"{name}_cartesian.png",
                                   f"{r.name}: {label} over the workspace\n{load}{others} "
                                   "deg\n(the largest value shown where poses overlap)")
        ok = ~table["singular"]
        summary = {
            "robot": r.name,
            "characteristic_length_m": length,
            "characteristic_length_method": how,
            "grid_step_deg": step,
            "nodes": int(len(table)),
            "singular_nodes": int((~ok).sum()),
            "max_v_p": float(table.loc[ok, "v_p"].max()),
            "max_v_r_deg": float(table.loc[ok, "v_r_deg"].max()),
            "max_inv_kappa_F": float(table["inv_kappa_F"].max()),
            "wrench_N_Nm": w.tolist(),
            "wrench_source": w_source,
            "joint_stiffness_Nm_per_rad": k.tolist(),
        }
        if bound_cols:
            summary["max_deflection_upper95_mm"] = float(
                table.loc[ok, "deflection_upper95_mm"].max())
            summary["deflection_upper95_method"] = BOUND_TEXT
        write_text(out / "map_summary.json", json.dumps(summary, indent=2) + "\n")
        if as_json:
            print_json({**summary, "files": sorted(str(p) for p in out.iterdir())})
            return
        print_wrapped(console,
            f"{len(table)} poses, {summary['singular_nodes']} singular; "
            f"max v_p = {summary['max_v_p']:.4f}, max v_r = {summary['max_v_r_deg']:.4f} deg, "
            f"max 1/kappa_F = {summary['max_inv_kappa_F']:.3f}"
        )
        if bound_cols:
            with_kc = table.loc[ok]
            at = with_kc["deflection_upper95_mm"].idxmax()
            print_wrapped(console, f"95 % upper bound of |dp|: at most "
                          f"{summary['max_deflection_upper95_mm']:.4g} mm over the grid (at "
                          f"theta2 = {with_kc.loc[at, 'theta2_deg']:.4g} deg, theta3 = "
                          f"{with_kc.loc[at, 'theta3_deg']:.4g} deg); column "
                          "deflection_upper95_mm and deflection_upper95_*.png")
        print_wrapped(console, f"wrote {data} and PNG plots to {out}/")
