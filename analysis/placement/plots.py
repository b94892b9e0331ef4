"""Plots of ``campaign place`` (matplotlib, Agg backend, imported only when drawing)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.output_files import save_figure


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_objective_map(xs_mm, ys_mm, values, best_xy_mm, title: str, unit: str,
                       path: Path) -> None:
    """Objective over the x-y grid (values (nx, ny), NaN where infeasible); ``unit`` is the
    colour bar's whole label (what and unit). The legend is under the axes: inside, it
    would hide cells."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(6, 5))
    masked = np.ma.masked_invalid(values.T)
    if len(xs_mm) > 1 and len(ys_mm) > 1:
        mesh = ax.pcolormesh(xs_mm, ys_mm, masked, shading="nearest", cmap="viridis")
        fig.colorbar(mesh, ax=ax, label=unit)
    else:
        sc = ax.scatter(np.repeat(xs_mm, len(ys_mm)), np.tile(ys_mm, len(xs_mm)),
                        c=values.ravel(), cmap="viridis")
        fig.colorbar(sc, ax=ax, label=unit)
    ax.plot(*best_xy_mm, "r*", markersize=14, label="best")
    ax.set_xlabel("x of the workpiece origin (mm, base frame)")
    ax.set_ylabel("y of the workpiece origin (mm, base frame)")
    ax.set_title(title + "\n(blank: infeasible)", fontsize=9)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), frameon=False, fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def plot_path_deflection(best_mm: np.ndarray, center_mm: np.ndarray | None, title: str,
                         path: Path, best_upper_mm: np.ndarray | None = None) -> None:
    """|dp| (mm) along the path at the best placement (with its 95 % band up to
    ``best_upper_mm`` when the model carries the stiffness covariance) and at the centre of
    the box."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    n = np.arange(1, best_mm.size + 1)
    line, = ax.plot(n, best_mm, label="best placement")
    if best_upper_mm is not None:
        lower = np.maximum(2 * best_mm - best_upper_mm, 0.0)
        ax.fill_between(n, lower, best_upper_mm, color=line.get_color(), alpha=0.2, lw=0,
                        label="best placement: 95 % band (stiffness uncertainty)")
    if center_mm is not None:
        ax.plot(n, center_mm, label="centre of the search box")
    ax.set_xlabel("path point")
    ax.set_ylabel(r"translational deflection $|\delta p|$ of P (mm)")
    ax.set_title(title, fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
