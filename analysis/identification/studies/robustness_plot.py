"""The robustness study's figure (the paper's Fig. 7) and which of its rows identify k.

The study's table: :func:`analysis.identification.studies.robustness.robustness_study`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

#: a number of tests is shown as not identifiable when more than this fraction of the
#: trials is rejected, or the IQR / 1.349 of k exceeds k itself
NOT_IDENTIFIABLE_REJECTED = 0.10


def identifiable_rows(summary: pd.DataFrame) -> np.ndarray:
    """(rows,) bool: the (n_tests, joint) rows where the design identifies k (few trials
    rejected, a spread below the value)."""
    rejected = summary["trials_rejected"] / summary["trials"].clip(lower=1)
    spread = summary["iqr_Nm_per_rad"] / 1.349
    return ((rejected <= NOT_IDENTIFIABLE_REJECTED)
            & (spread < summary["k_true_Nm_per_rad"])).to_numpy(dtype=bool)


def plot_study(summary: pd.DataFrame, path, title: str = "", subtitle: str = "") -> None:
    """PNG like the paper's Fig. 7: median and IQR of each k (kN m/rad) vs number of tests,
    the mean +- std beside them; numbers of tests where the design is not identifiable are
    marked at the top (their spread would otherwise set the scale) and left out."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.transforms import blended_transform_factory

    joints = sorted(summary["joint"].unique())
    good = identifiable_rows(summary)
    fig, axes = plt.subplots(2, 3, figsize=(11, 6.8), sharex=True)
    for ax, j in zip(axes.flat, joints, strict=False):
        sel = (summary["joint"] == j).to_numpy()
        s, ok = summary[sel], good[sel]
        n = s["n_tests"].to_numpy()
        med = s["median_Nm_per_rad"].to_numpy() / 1e3
        q25 = (s["q25_Nm_per_rad"].to_numpy() if "q25_Nm_per_rad" in s else
               s["median_Nm_per_rad"].to_numpy() - s["iqr_Nm_per_rad"].to_numpy() / 2) / 1e3
        q75 = q25 + s["iqr_Nm_per_rad"].to_numpy() / 1e3
        mean = s["mean_Nm_per_rad"].to_numpy() / 1e3
        std = s["std_Nm_per_rad"].to_numpy() / 1e3
        ax.errorbar(n[ok], med[ok], yerr=[med[ok] - q25[ok], q75[ok] - med[ok]], fmt="o-",
                    ms=3, capsize=2, label="median, IQR")
        # the mean and std where they mean something: not blown up by a few wild draws
        # (std within twice the IQR's normal equivalent)
        fair = ok & (std <= 2 * (q75 - q25) / 1.349)
        ax.errorbar(n[fair] + 0.25, mean[fair], yerr=std[fair], fmt="s", ms=2, capsize=1.5,
                    color="0.55", lw=0.8, label="mean \u00b1 std (where std \u2264 2 IQR/1.349)")
        ax.axhline(s["k_true_Nm_per_rad"].iloc[0] / 1e3, color="k", ls="--", lw=1,
                   label="true")
        if (~ok).any():
            trans = blended_transform_factory(ax.transData, ax.transAxes)
            ax.plot(n[~ok], [0.95] * int((~ok).sum()), "x", color="tab:red", ms=6,
                    transform=trans, clip_on=False, label="not identifiable")
        if ok.any():
            true = s["k_true_Nm_per_rad"].iloc[0] / 1e3
            lo = min(q25[ok].min(), (mean - std)[fair].min(initial=true), true)
            hi = max(q75[ok].max(), (mean + std)[fair].max(initial=true), true)
            pad = 0.08 * (hi - lo) if hi > lo else 0.05 * abs(hi) + 1e-9
            ax.set_ylim(lo - pad, hi + pad)
        ax.set_title(f"$k_{j}$", fontsize=10)
        ax.set_ylabel("kN m/rad")
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("number of tests")
    handles, labels = [], []
    for ax in axes.flat:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=8, frameon=False)
    fig.suptitle((title or "Identified joint stiffness vs number of tests")
                 + (f"\n{subtitle}" if subtitle else ""), fontsize=10)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    from analysis.output_files import save_figure

    save_figure(fig, path, dpi=150)
    plt.close(fig)
