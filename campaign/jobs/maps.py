"""The ``maps`` job: 1/kappa_F, v_p and v_r over the (theta_2, theta_3) grid and the workspace
(the paper's Figs. 3 and 5); writes the map table, the PNG plots and map_summary.json."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from analysis.errors import InputError
from campaign.jobs.choices import TableFormat
from campaign.jobs.option_checks import (
    Note,
    Stage,
    floats,
    joint_stiffness,
    no_note,
    no_stage,
    robot_and_tool,
    wrench,
)

#: what --deflection-upper-bound maps, said when it is used
BOUND_TEXT = ("deflection upper bound: |dp| + 1.96 sd(|dp|), the 95 % upper bound of |dp| "
              "(linear model with K_C, the maps' model), sd from the identified compliances' "
              "covariance (the robot file's [identification]) by the delta method along dp")


@dataclass(frozen=True)
class MapsOptions:
    """robot, tip, tool_xyz_mm / tool_rpy_deg: as :class:`campaign.jobs.stiffness.StiffnessOptions`;
    out: the output directory; step_rad: grid step (rad);
    fixed_rad: the other joints q1..q6 (rad, model convention; entries 2 and 3 ignored;
    None: theta1 = 0, theta4..6 = 45 deg as in the paper);
    joint_stiffness_Nm_per_rad, wrench_N_Nm: None = nominal values, the paper's worst case;
    length_m: characteristic length (None: the model's, else computed);
    format: map table format; upper_bound: also map the 95 % upper bound of |dp| from an
    identified model's covariance; force: replace the map files of a non-empty ``out``."""

    robot: str
    out: Path
    tip: str | None = None
    tool_xyz_mm: Sequence[float] | None = None
    tool_rpy_deg: Sequence[float] | None = None
    step_rad: float = float(np.radians(1.0))
    fixed_rad: Sequence[float] | None = None
    joint_stiffness_Nm_per_rad: Sequence[float] | None = None
    wrench_N_Nm: Sequence[float] | None = None
    length_m: float | None = None
    format: TableFormat = TableFormat.parquet
    upper_bound: bool = False
    force: bool = False


@dataclass
class MapsResult:
    """summary: OUT/map_summary.json (SI units; the grid step in deg as labelled);
    data_file: the map table; files: every file of OUT."""

    summary: dict
    data_file: Path
    files: list[str] = field(default_factory=list)
    #: (theta2, theta3) in deg of the largest 95 % upper bound of |dp| (None: not mapped)
    bound_at_deg: tuple[float, float] | None = None

    def to_json(self) -> dict:
        """The document ``campaign maps --json`` prints."""
        return {**self.summary, "files": self.files}


def step_deg(step_rad: float) -> float:
    """The grid step in degrees as typed (12 significant digits undo the deg -> rad trip)."""
    return float(f"{np.degrees(step_rad):.12g}")


def run(o: MapsOptions, stage: Stage = no_stage, note: Note = no_note) -> MapsResult:
    """Compute the maps and write them; ``note`` gets the characteristic length used."""
    # pinocchio, scipy, pandas and matplotlib: imported when the job runs
    from analysis.kinetostatics.dexterity import characteristic_length
    from analysis.kinetostatics.map_plots import LABELS, plot_cartesian_map, plot_joint_map
    from analysis.kinetostatics.maps import WORST_CASE_WRENCH, GridSpec, joint_space_map
    from analysis.output_files import check_output_dir, make_dir, replacing, write_text
    from analysis.report.build import wrench_text

    r, _ = robot_and_tool(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    step = step_deg(o.step_rad)
    if not (np.isfinite(o.step_rad) and o.step_rad > 0):
        raise InputError("expected a positive step in degrees", where="--step")
    fmt = str(o.format)
    if fmt not in ("parquet", "csv"):
        raise InputError("expected parquet or csv", where="--format")
    k = joint_stiffness(r, o.joint_stiffness_Nm_per_rad)
    w = wrench(o.wrench_N_Nm, WORST_CASE_WRENCH)
    fixed_q = None if o.fixed_rad is None else floats(o.fixed_rad, "--fixed", r.n)
    length = o.length_m
    if length is not None and not length > 0:
        raise InputError("expected a positive length in m", where="--length")
    how = "given on the command line"
    if length is None and r.characteristic_length is not None:
        length, how = r.characteristic_length, "from the robot model"
    elif length is None:
        with stage("characteristic length"):
            length, _, _ = characteristic_length(r)
        how = "computed (minimum condition number of J_N over posture and L)"
    out = Path(o.out)
    check_output_dir(out, o.force)
    from analysis.report.formatting import k_kNm
    from campaign.jobs.stiffness import WORST_CASE_TEXT
    from campaign.numbers_text import vector_text

    w_source = "--wrench" if o.wrench_N_Nm is not None else WORST_CASE_TEXT
    note(f"wrench w = {vector_text(w[:3], 6, False)} N, "
         f"{vector_text(w[3:], 6, False)} N m at P, base frame ({w_source})")
    note(f"joint stiffness [{', '.join(k_kNm(v) for v in k)}] kN m/rad ("
         + ("--joint-stiffness" if o.joint_stiffness_Nm_per_rad is not None
            else "the robot model's") + ")")
    note(f"characteristic length L = {length:.4f} m ({how})")
    from analysis.kinetostatics.compensator_law import compensator_law_of, law_uncertainty_text

    law = compensator_law_of(r)
    if law is not None:  # v_p, v_r, the deflection (and its bound) take k2(q2) per node
        note(f"joint 2 per node from the {law.text()} (k2 above taken at q2ref)")
    grid = GridSpec.from_limits(r, o.step_rad, fixed_q)
    with stage(f"map of {r.name} ({step:g} deg grid)"):
        table = joint_space_map(r, grid, k, w, length)
    bound_cols = []
    if o.upper_bound:
        if r.compliance_covariance is None or o.joint_stiffness_Nm_per_rad is not None:
            raise InputError("--deflection-upper-bound needs an identified model "
                             "(model.toml from campaign analyze) and no --joint-stiffness",
                             where="--deflection-upper-bound")
        from analysis.kinetostatics.uncertainty import linear_deflection_upper_bound

        table["deflection_upper95_mm"] = 1e3 * linear_deflection_upper_bound(
            r, grid.poses(), k, w, r.compliance_covariance).ravel()
        bound_cols = [("deflection_upper95_mm", "deflection_upper95")]
        note(BOUND_TEXT + ("; " + law_uncertainty_text(r) if law is not None else ""))
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
    if law is not None:
        summary["compensator_law"] = law.text()
    at_deg = None
    if bound_cols:
        summary["max_deflection_upper95_mm"] = float(
            table.loc[ok, "deflection_upper95_mm"].max())
        summary["deflection_upper95_method"] = BOUND_TEXT + (
            "; " + law_uncertainty_text(r) if law is not None else "")
        with_kc = table.loc[ok]
        at = with_kc["deflection_upper95_mm"].idxmax()
        at_deg = (float(with_kc.loc[at, "theta2_deg"]), float(with_kc.loc[at, "theta3_deg"]))
    write_text(out / "map_summary.json", json.dumps(summary, indent=2) + "\n")
    return MapsResult(summary, data, sorted(str(p) for p in out.iterdir()), at_deg)
