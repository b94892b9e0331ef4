"""The trend figure of ``campaign history trend --plot``: k per joint over the campaigns.

Six panels, one per joint: each campaign's stiffness (kN m/rad, the plot's labelled
edge) with its recorded 95 % interval, the reference's value as a dashed line,
campaigns left out of the statistics drawn hollow.
"""

from __future__ import annotations

from pathlib import Path


def plot_trend(trend: dict, path: Path) -> Path:
    """Write the figure of ``trend`` (the document of ``history trend --json``) to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = trend["campaigns"]
    fig, axes = plt.subplots(3, 2, figsize=(9, 8), sharex=True)
    xs = list(range(1, len(rows) + 1))
    ref = next((r for r in rows if r["reference"]), None)
    for j, ax in enumerate(axes.flat):
        for x, r in zip(xs, rows, strict=True):
            k, ci = r["k_Nm_per_rad"][j], r["ci95_Nm_per_rad"][j]
            if k is None:
                continue
            lo, hi = (ci if ci is not None and None not in ci else (k, k))
            ax.errorbar([x], [k / 1e3], yerr=[[(k - lo) / 1e3], [(hi - k) / 1e3]], fmt="o",
                        color="C0", mfc="C0" if r["compared"] else "white", capsize=3)
        if ref is not None and ref["k_Nm_per_rad"][j] is not None:
            ax.axhline(ref["k_Nm_per_rad"][j] / 1e3, ls="--", color="0.5", lw=1)
        ax.set_title(f"joint {j + 1}")
        ax.set_ylabel("k (kN m/rad)")
    for ax in axes[-1]:
        ax.set_xticks(xs, [r["date"][:10] for r in rows], rotation=45, ha="right")
    fig.suptitle(f"Robot {trend['robot']}: joint stiffness per campaign, 95 % intervals "
                 "(hollow: not compared)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
