"""The plot of ``campaign compare``: (k_B - k_A)/k_A per joint with the verdict's interval."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np

from analysis.errors import InputError

#: file types the plot is written as (by the name's suffix)
PLOT_SUFFIXES = (".png", ".pdf", ".svg")


def check_plot_path(path: Path, option: str = "--plot") -> Path:
    """Refuses a plot path that cannot be written, before anything is computed."""
    path = Path(path)
    if path.is_symlink():
        raise InputError(f"{path} is a symbolic link: refused (write to a plain file)",
                         where=option)
    if path.is_dir():
        raise InputError(f"{path} is a directory: give a file name such as "
                         f"{path / 'compare.png'}", where=option)
    if path.suffix.lower() not in PLOT_SUFFIXES:
        raise InputError(f"{path}: expected a file name ending in "
                         f"{', '.join(PLOT_SUFFIXES)}", where=option)
    parent = path.parent
    if parent.is_symlink() or not parent.is_dir():
        raise InputError(f"the directory {parent} does not exist" if not parent.exists()
                         else f"{parent} is not a directory", where=option)
    if not os.access(parent, os.W_OK):
        raise InputError(f"the directory {parent} is not writable", where=option)
    return path


def run_names(result: dict) -> list[str]:
    """'A: campaign, measured DATE, ROBOT (simulated)' for A and B: the facts of each
    side's results.json and run metadata (:func:`~analysis.identification.compare.
    run_facts.run_facts`), else its path."""
    from analysis.identification.compare.run_facts import run_facts

    out = []
    for label in ("A", "B"):
        source = str(result.get(label, "-"))
        try:
            f = run_facts(label, source)
        except (OSError, ValueError):
            out.append(f"{label}: {source}")
            continue
        name = f.campaign or Path(f.results).parent.parent.name or f.results
        date = f", measured {f.started}" if f.started and f.started != "-" else ""
        out.append(f"{label}: {name}{date}, {f.robot}" + (" (simulated)" if f.simulated
                                                          else ""))
    return out


def plot_comparison(result: dict, path: Path) -> Path:
    """Write the plot to ``path`` (through a temporary file beside it: nothing is left
    behind on failure). Intervals at the verdict's level (``result['interval_level']``)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path = check_plot_path(Path(path))
    rows = result["joints"]
    x = np.arange(len(rows))
    rel = np.array([100 * r["relative_difference"] for r in rows])
    iv = [r["interval_difference_Nm_per_rad"] for r in rows]
    lo = np.array([100 * v[0] / r["k_A_Nm_per_rad"] for v, r in zip(iv, rows, strict=True)])
    hi = np.array([100 * v[1] / r["k_A_Nm_per_rad"] for v, r in zip(iv, rows, strict=True)])
    colors = ["tab:red" if r["verdict"] == "changed" else "tab:gray" for r in rows]
    level = 100 * result["interval_level"]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.axhline(0, color="black", lw=0.8)
    ax.errorbar(x, rel, yerr=[rel - lo, hi - rel], fmt="none", ecolor="black", capsize=4)
    ax.scatter(x, rel, c=colors, zorder=3)
    ax.set_xticks(x, [f"$k_{r['joint']}$" for r in rows])
    ax.set_ylabel(f"$(k_B - k_A)/k_A$ (%), {level:.4g} % interval")
    ax.set_title(f"{result['robot']}: B vs A (red: changed); intervals at {level:.4g} % = "
                 f"1 - alpha/{len(rows)}, alpha {result['alpha']:g} (Bonferroni)\n"
                 + "\n".join(run_names(result)), fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=path.suffix, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fig.savefig(fh, dpi=120, format=path.suffix.lower()[1:])
        os.replace(tmp, path)
    except OSError as err:
        raise InputError(f"cannot write the plot: {err.strerror or err}", where=str(path)) \
            from None
    finally:
        plt.close(fig)
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
