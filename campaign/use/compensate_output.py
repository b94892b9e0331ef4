"""Files of ``campaign compensate``: compensated.csv, the plot, the summary, the robot program."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.kinetostatics.path_compensation import PathCompensation
from analysis.kinetostatics.uncertainty import Z95, norm_upper_bound
from analysis.model.robot_model import RobotModel

D_COLS = ["dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"]


def output_table(frame, pc: PathCompensation, robot: RobotModel, controller: bool):
    """The input columns, the predicted deflection, its 95 % bounds, the compensated joints."""
    import pandas as pd

    out = frame.copy()
    lo, hi = pc.before.bounds(Z95)
    for j, col in enumerate(D_COLS):
        out[col] = 1e3 * pc.before.screw[:, j]
    for j, col in enumerate(D_COLS):
        stem, unit = col.rsplit("_", 1)
        out[f"{stem}_lo95_{unit}"] = 1e3 * lo[:, j]
        out[f"{stem}_hi95_{unit}"] = 1e3 * hi[:, j]
    q_cmd = robot.to_controller(pc.comp.q_cmd) if controller else pc.comp.q_cmd
    for j in range(robot.n):
        out[f"q{j + 1}_cmd_deg"] = np.degrees(q_cmd[:, j])
    out["residual_um"] = 1e6 * np.linalg.norm(pc.comp.residual[:, :3], axis=1)
    out["residual_urad"] = 1e6 * np.linalg.norm(pc.comp.residual[:, 3:], axis=1)
    return pd.DataFrame(out)


def norms(pc: PathCompensation) -> dict[str, np.ndarray]:
    """|dp| (m), |dr| (rad) before and after compensation, with their 95 % upper bounds."""
    b, cb, ca = pc.before.screw, pc.before.cov, pc.after_cov
    r = pc.comp.residual
    return {
        "before_p": np.linalg.norm(b[:, :3], axis=1),
        "before_r": np.linalg.norm(b[:, 3:], axis=1),
        "before_p_hi": norm_upper_bound(b[:, :3], cb[:, :3, :3]),
        "before_r_hi": norm_upper_bound(b[:, 3:], cb[:, 3:, 3:]),
        "after_p": np.linalg.norm(r[:, :3], axis=1),
        "after_r": np.linalg.norm(r[:, 3:], axis=1),
        # the error left is zero-mean: bound it in its worst direction (the model's
        # residual, ~1e-15, would otherwise pick a random direction)
        "after_p_hi": norm_upper_bound(np.zeros_like(r[:, :3]), ca[:, :3, :3]),
        "after_r_hi": norm_upper_bound(np.zeros_like(r[:, 3:]), ca[:, 3:, 3:]),
    }


def summary(pc: PathCompensation, lines: np.ndarray) -> dict:
    """Max and RMS deflection before/after (predicted by the model), worst point, SI."""
    n = norms(pc)
    worst = int(np.argmax(n["before_p"]))

    def stats(v):
        return {"max": float(v.max()), "rms": float(np.sqrt(np.mean(v**2)))}

    return {
        "points": int(len(lines)),
        "translation_m": {"before": stats(n["before_p"]), "after": stats(n["after_p"]),
                          "before_upper95_max": float(n["before_p_hi"].max()),
                          "after_upper95_max": float(n["after_p_hi"].max())},
        "rotation_rad": {"before": stats(n["before_r"]), "after": stats(n["after_r"]),
                         "before_upper95_max": float(n["before_r_hi"].max()),
                         "after_upper95_max": float(n["after_r_hi"].max())},
        "worst_point": {"line": int(lines[worst]), "point": int(lines[worst]) - 1,
                        "deflection_m": float(n["before_p"][worst])},
        "max_residual_m": float(n["after_p"].max()),
        "max_residual_rad": float(n["after_r"].max()),
        "newton_iterations": int(pc.comp.iterations),
        "min_inv_kappa_F": float(pc.inv_kappa.min()),
        "characteristic_length_m": pc.length[0],
        "characteristic_length_source": pc.length[1],
    }


def plot(pc: PathCompensation, path: Path, title: str, measured=None) -> Path:
    """|dp| (mm) and |dr| (mrad) along the path: before (predicted, with its 95 % band) and
    after compensation (the 95 % upper bound from the stiffness uncertainty); with
    ``measured`` (:class:`campaign.use.verify_fake.FakeLabCheck`) the errors measured on the
    simulated lab before and after, as points. The legend is under the plots."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = norms(pc)
    x = np.arange(1, len(n["before_p"]) + 1)
    fig, axes = plt.subplots(2, 1, figsize=(9, 6.6), sharex=True)
    for ax, key, scale, unit in ((axes[0], "p", 1e3, "mm"), (axes[1], "r", 1e3, "mrad")):
        mid, hi = scale * n[f"before_{key}"], scale * n[f"before_{key}_hi"]
        ax.plot(x, mid, color="tab:red", label="before: predicted")
        # the band's lower edge mirrors its upper one about the prediction (positive)
        ax.fill_between(x, np.maximum(2 * mid - hi, 0.5 * mid), hi, color="tab:red",
                        alpha=0.25, lw=0, label="before: 95 % band")
        ax.plot(x, scale * n[f"after_{key}_hi"], color="tab:blue",
                label="after: predicted 95 % upper bound (stiffness uncertainty)")
        if measured is not None:
            sl = slice(0, 3) if key == "p" else slice(3, 6)
            for err, color, what in ((measured.before, "darkred", "before"),
                                     (measured.after, "navy", "after")):
                ax.plot(x, scale * np.linalg.norm(err[:, sl], axis=1), ".", ms=3,
                        color=color, label=f"{what}: measured on the simulated lab")
        ax.set_yscale("log")
        ax.set_ylabel(f"$|\\delta {'p' if key == 'p' else 'r'}|$ ({unit})")
        ax.grid(alpha=0.3, which="both")
    axes[1].set_xlabel("point of the path")
    axes[0].set_title(title + f"\nafter compensation the model's own residual is below "
                      f"{1e6 * n['after_p'].max():.2g} \u00b5m / "
                      f"{1e6 * n['after_r'].max():.2g} \u00b5rad", fontsize=9)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=2, fontsize=8, frameon=False)
    fig.tight_layout(rect=(0, 0.1 if measured is not None else 0.07, 1, 1))
    from analysis.output_files import save_figure

    save_figure(fig, path, dpi=150)
    plt.close(fig)
    return path


def robot_program(robot: RobotModel, q_cmd: np.ndarray, out: Path, comments: list[str],
                  kind: str = "auto") -> list[Path]:
    """The compensated path as a robot program in the pendant convention.

    ``kind``: ``krl``, ``urscript``, ``rapid``, ``fanuc-ls``, ``none``, or ``auto`` (KRL
    for KUKA, URScript for UR, RAPID for ABB, ``.LS`` for FANUC models; none otherwise).
    """
    from analysis.export.robot_programs import default_format, write_program

    if kind == "auto":
        kind = default_format(robot.name, robot.key) or "none"
    if kind == "none":
        return []
    return write_program(kind, out, "comp_path", robot.to_controller(q_cmd), comments)


def lost_motion_text(flanks, lines: np.ndarray) -> str:
    """The summary's line on the lost-motion flank offsets (rad in, deg out): how many
    points got them, and the CSV lines and joints where the torque side is unknown."""
    applied = int(np.sum(np.any(flanks.offset != 0, axis=1)))
    text = (f"lost motion (model file's [model_class]): the flank offset b_j sign(tau_j) "
            f"subtracted from the compensated joints at {applied} of {len(lines)} points "
            f"(up to {np.degrees(np.abs(flanks.offset).max()):.4g} deg)")
    bad = np.flatnonzero(np.any(flanks.unknown, axis=1))
    if bad.size:
        shown = ", ".join(f"line {int(lines[i])} (joint "
                          + ", ".join(str(j + 1) for j in np.flatnonzero(flanks.unknown[i]))
                          + ")" for i in bad[:5])
        more = f" and {bad.size - 5} more points" if bad.size > 5 else ""
        text += (f"; NOT applied where the torque side is unknown, {bad.size} points: "
                 f"{shown}{more} ({flanks.why}): the output there can sit anywhere in the "
                 "band")
    return text
