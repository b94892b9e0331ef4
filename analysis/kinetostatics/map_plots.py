"""PNG plots of maps: joint space (paper Figs. 3b, 5) and Cartesian workspace (Fig. 3a)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

LABELS = {
    "inv_kappa_F": "1/kappa_F of J_N",
    "v_p": "v_p (translational influence of K_C)",
    "v_r_deg": "v_r (deg)",
    "deflection_mm": "translational deflection (mm)",
}


def plot_joint_map(
    table: pd.DataFrame,
    column: str,
    path: str | Path,
    title: str,
    points: pd.DataFrame | None = None,
    zones: list | None = None,
) -> Path:
    """Filled contours of ``column`` over (theta_2, theta_3) in degrees, singular nodes hatched.

    ``points`` (columns theta2_deg, theta3_deg) are overlaid, e.g. planned poses;
    ``zones`` is a list of (name, (t2lo, t2hi), (t3lo, t3hi)) boxes in degrees.
    """
    t2 = np.unique(table["theta2_deg"].to_numpy())
    t3 = np.unique(table["theta3_deg"].to_numpy())
    grid = table.pivot_table(index="theta3_deg", columns="theta2_deg", values=column)
    sing = table.pivot_table(index="theta3_deg", columns="theta2_deg", values="singular")
    fig, ax = plt.subplots(figsize=(7.0, 5.5), dpi=110)
    cs = ax.contourf(t2, t3, grid.to_numpy(), levels=20, cmap="viridis")
    fig.colorbar(cs, ax=ax, label=LABELS.get(column, column))
    if sing.to_numpy().any():
        ax.contourf(t2, t3, sing.to_numpy().astype(float), levels=[0.5, 1.5], colors="none",
                    hatches=["xxx"])
        ax.plot([], [], "s", color="white", markeredgecolor="k", label="singular (hatched)")
    for name, (a, b), (c, d) in zones or []:
        ax.add_patch(plt.Rectangle((a, c), b - a, d - c, fill=False, ec="red", lw=1.5))
        # inside the box (never clipped by the frame), on white (readable on any colour map)
        ax.text(a, d, f"{name}", color="darkred", va="top", ha="left", fontsize=8,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none",
                      "alpha": 0.85})
    if points is not None and len(points):
        ax.plot(points["theta2_deg"], points["theta3_deg"], "o", mfc="white", mec="k",
                mew=1.5, clip_on=False, zorder=5, label="planned poses")
    ax.set_xlabel("theta_2 (deg, model convention)")
    ax.set_ylabel("theta_3 (deg, model convention)")
    ax.set_title(title, fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path = Path(path)
    from analysis.output_files import save_figure

    save_figure(fig, path)
    plt.close(fig)
    return path


def plot_cartesian_map(table: pd.DataFrame, column: str, path: str | Path, title: str) -> Path:
    """``column`` over the positions of P in the arm's plane (x, z), as the paper's Fig. 3a."""
    ok = ~table["singular"].to_numpy()
    radial = np.hypot(table["x_m"], table["y_m"]) * np.sign(table["x_m"].where(
        table["x_m"] != 0, 1.0))
    fig, ax = plt.subplots(figsize=(7.0, 5.5), dpi=110)
    sc = ax.scatter(radial[ok], table["z_m"][ok], c=table[column][ok], s=4, cmap="viridis")
    if (~ok).any():
        ax.scatter(radial[~ok], table["z_m"][~ok], c="red", s=6, marker="x", label="singular")
        ax.legend(loc="upper right", fontsize=8)
    fig.colorbar(sc, ax=ax, label=LABELS.get(column, column))
    ax.set_xlabel("horizontal distance of P from axis 1 (m)")
    ax.set_ylabel("height of P (m)")
    ax.set_aspect("equal")
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    path = Path(path)
    from analysis.output_files import save_figure

    save_figure(fig, path)
    plt.close(fig)
    return path
