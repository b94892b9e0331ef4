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
    """Objective over the x-y grid (values (nx, ny), NaN where infeasible)."""
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
    ax.set_title(title + "\n(blank: infeasible)")
    ax.legend(loc="best")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)


def plot_path_deflection(best_mm: np.ndarray, center_mm: np.ndarray | None, title: str,
                         path: Path) -> None:
    """|dp| (mm) along the path at the best placement and at the centre of the box."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4))
    n = np.arange(1, best_mm.size + 1)
    ax.plot(n, best_mm, label="best placement")
    if center_mm is not None:
        ax.plot(n, center_mm, label="centre of the search box")
    ax.set_xlabel("path point")
    ax.set_ylabel("translational deflection of P (mm)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best")
    fig.tight_layout()
    save_figure(fig, path, dpi=120)
    plt.close(fig)
