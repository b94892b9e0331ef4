"""PNG plots of maps: joint space (paper Figs. 3b, 5) and Cartesian workspace (Fig. 3a)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

#: colour-bar labels in mathtext (no literal underscore drawn)
LABELS = {
    "inv_kappa_F": r"$1/\kappa_F$ of $J_N$",
    "v_p": r"$v_p$ (translational influence of $K_C$)",
    "v_r_deg": r"$v_r$ (deg)",
    "deflection_mm": r"translational deflection $|\delta p|$ (mm)",
    "deflection_upper95_mm": r"95 % upper bound of $|\delta p|$ (mm)",
}


def _label(column: str) -> str:
    return LABELS.get(column, column.replace("_", " "))


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
    fig.colorbar(cs, ax=ax, label=_label(column))
    if sing.to_numpy().any():
        ax.contourf(t2, t3, sing.to_numpy().astype(float), levels=[0.5, 1.5], colors="none",
                    hatches=["xxx"])
        ax.plot([], [], "s", color="white", markeredgecolor="k", label="singular (hatched)")
    lo2, hi2, lo3, hi3 = t2.min(), t2.max(), t3.min(), t3.max()
    for name, (a, b), (c, d) in zones or []:
        # not clipped: a zone on a joint limit has its edge on the frame
        ax.add_patch(plt.Rectangle((a, c), b - a, d - c, fill=False, ec="red", lw=1.5,
                                   clip_on=False, zorder=4))
        # inside the box, on white (readable on any colour map), never clipped
        ax.text(max(a, lo2), min(d, hi3), f"{name}", color="darkred", va="top", ha="left",
                fontsize=8, clip_on=False, zorder=4,
                bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none",
                      "alpha": 0.85})
        lo2, hi2, lo3, hi3 = min(lo2, a), max(hi2, b), min(lo3, c), max(hi3, d)
    pad2, pad3 = 0.01 * (hi2 - lo2), 0.01 * (hi3 - lo3)
    ax.set_xlim(lo2 - pad2, hi2 + pad2)
    ax.set_ylim(lo3 - pad3, hi3 + pad3)
    if points is not None and len(points):
        ax.plot(points["theta2_deg"], points["theta3_deg"], "o", mfc="white", mec="k",
                mew=1.5, clip_on=False, zorder=5, label="planned poses")
    ax.set_xlabel(r"$\theta_2$ (deg, model convention)")
    ax.set_ylabel(r"$\theta_3$ (deg, model convention)")
    ax.set_title(title, fontsize=8.5)
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
    # several configurations reach one position of P: drawn in increasing order, the
    # largest value is the one seen where they overlap (no seams of whichever came last)
    values = table[column].to_numpy(dtype=float)
    order = np.flatnonzero(ok)[np.argsort(values[ok], kind="stable")]
    sc = ax.scatter(radial.to_numpy()[order], table["z_m"].to_numpy()[order], c=values[order],
                    s=4, cmap="viridis")
    if (~ok).any():
        ax.scatter(radial[~ok], table["z_m"][~ok], c="red", s=6, marker="x", label="singular")
        ax.legend(loc="upper right", fontsize=8)
    fig.colorbar(sc, ax=ax, label=_label(column))
    ax.set_xlabel("horizontal distance of P from axis 1 (m)")
    ax.set_ylabel("height of P (m)")
    ax.set_aspect("equal")
    # over the whole figure: the equal-aspect axes are narrower than a long title
    fig.suptitle(title, fontsize=8.5)
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    path = Path(path)
    from analysis.output_files import save_figure

    save_figure(fig, path)
    plt.close(fig)
    return path
