"""Compare two identifications of the same robot: did the joint stiffness change?

Per joint identified in both campaigns A and B (independent measurements):

* the difference ``k_B - k_A`` (N m/rad) with its 95 % interval
  ``+- 1.96 sqrt(se_A^2 + se_B^2)`` (standard errors of k by the delta method);
* a z score computed on the compliances x = 1/k, whose estimates are the
  (near-normal) least-squares ones: ``z = (x_B - x_A) / sqrt(var_A + var_B)``;
* a verdict "changed" when ``|z|`` exceeds the two-sided critical value at
  ``alpha / m`` (Bonferroni over the m joints compared), so that for two
  campaigns of an unchanged robot the probability of any "changed" verdict
  (the false-alarm rate) is at most ``alpha`` (default 5 %); otherwise
  "no evidence of change".
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from analysis.errors import InputError

ALPHA = 0.05


@dataclass
class Campaign:
    """One identification as read from results.json (SI).

    k, x (n,) stiffness (N m/rad, NaN if not identified) and compliance;
    cov_x (n, n) compliance covariance (zero for joints not identified);
    joints : 0-based identified joints; model : model.toml beside it (mapping) or None.
    """

    source: str
    robot: str
    k: np.ndarray
    x: np.ndarray
    cov_x: np.ndarray
    joints: tuple[int, ...]
    model: dict | None = None


def _results_path(path: Path) -> Path:
    if path.is_file():
        return path
    for cand in (path / "results.json", path / "analysis" / "results.json"):
        if cand.is_file():
            return cand
    raise InputError("no results.json here (expected a run directory, its analysis "
                     "directory, or a results.json file)", where=str(path))


def load_campaign(path: str | Path) -> Campaign:
    """Read a run directory, an analysis directory or a results.json file."""
    rp = _results_path(Path(path))
    try:
        doc = json.loads(rp.read_text())
    except (OSError, json.JSONDecodeError) as err:
        raise InputError(f"cannot read results.json: {err}", where=str(rp)) from None
    try:
        joints = tuple(int(j) - 1 for j in doc["joints_identified"])
        n = len(doc["joint_stiffness_Nm_per_rad"])
        k = np.array([np.nan if v is None else v for v in doc["joint_stiffness_Nm_per_rad"]])
        cov_p = np.asarray(doc["covariance_of_compliance"], dtype=float)
        robot = str(doc["robot"])
    except (KeyError, TypeError, ValueError) as err:
        raise InputError(f"not a results.json of campaign analyze (field {err})",
                         where=str(rp)) from None
    if cov_p.shape != (len(joints), len(joints)):
        raise InputError("covariance_of_compliance does not match joints_identified",
                         where=str(rp))
    cov = np.zeros((n, n))
    cov[np.ix_(joints, joints)] = cov_p
    with np.errstate(divide="ignore"):
        x = np.where(np.isfinite(k) & (k > 0), 1.0 / k, np.nan)
    model = None
    mp = rp.parent / "model.toml"
    if mp.is_file():
        import tomllib

        model = tomllib.loads(mp.read_text())
    return Campaign(str(rp), robot, k, x, cov, joints, model)


def _geometry(model: dict) -> dict:
    keys = ("convention", "length_unit", "angle_unit", "limits_convention")
    joints = [{k: v for k, v in j.items() if k != "stiffness"} for j in model.get("joints", [])]
    return {**{k: model.get(k) for k in keys}, "joints": joints, "tool": model.get("tool")}


def check_comparable(a: Campaign, b: Campaign) -> list[int]:
    """Joints (0-based) identified in both; refuses different robots or conventions."""
    if Path(a.source).resolve() == Path(b.source).resolve():
        raise InputError("A and B are the same results file: a comparison needs two "
                         "independent campaigns", where=a.source)
    if a.robot != b.robot:
        raise InputError(f"different robots: {a.robot!r} ({a.source}) and {b.robot!r} "
                         f"({b.source})", where="campaign compare")
    if a.model is not None and b.model is not None:
        ga, gb = _geometry(a.model), _geometry(b.model)
        for key in ga:
            if ga[key] != gb[key]:
                raise InputError(f"the model files differ in {key} (conventions, geometry or "
                                 "tool): the stiffness values are not comparable",
                                 where=f"{a.source} vs {b.source}")
    common = sorted(set(a.joints) & set(b.joints))
    if not common:
        raise InputError("no joint identified in both campaigns", where="campaign compare")
    for c in (a, b):
        bad = [j + 1 for j in common if not (np.isfinite(c.x[j]) and c.cov_x[j, j] > 0)]
        if bad:
            raise InputError(f"joint(s) {bad} have no usable estimate or variance",
                             where=c.source)
    return common


def critical_z(alpha: float, m: int) -> float:
    """Two-sided normal critical value at alpha / m (Bonferroni over m joints)."""
    from scipy import special  # norm.isf, without importing scipy.stats

    return float(-special.ndtri(alpha / (2 * m)))


def z_scores(x_a, var_a, x_b, var_b) -> np.ndarray:
    """z = (x_B - x_A) / sqrt(var_A + var_B), batched (compliances, independent campaigns)."""
    return (np.asarray(x_b) - np.asarray(x_a)) / np.sqrt(np.asarray(var_a) + np.asarray(var_b))


def compare(a: Campaign, b: Campaign, alpha: float = ALPHA) -> dict:
    """Per-joint difference, 95 % interval, z score and verdict (see module docstring)."""
    if not 0 < alpha < 1:
        raise InputError("expected 0 < alpha < 1", where="--alpha")
    common = check_comparable(a, b)
    zc = critical_z(alpha, len(common))
    rows = []
    for j in common:
        z = float(z_scores(a.x[j], a.cov_x[j, j], b.x[j], b.cov_x[j, j]))
        se_a = math.sqrt(a.cov_x[j, j]) * a.k[j] ** 2
        se_b = math.sqrt(b.cov_x[j, j]) * b.k[j] ** 2
        diff = float(b.k[j] - a.k[j])
        half = 1.959963984540054 * math.hypot(se_a, se_b)
        rows.append({
            "joint": j + 1, "k_A_Nm_per_rad": float(a.k[j]), "k_B_Nm_per_rad": float(b.k[j]),
            "se_A_Nm_per_rad": se_a, "se_B_Nm_per_rad": se_b,
            "difference_Nm_per_rad": diff, "relative_difference": diff / float(a.k[j]),
            "ci95_difference_Nm_per_rad": [diff - half, diff + half],
            "z": z, "verdict": "changed" if abs(z) > zc else "no evidence of change",
        })
    return {
        "robot": a.robot, "A": a.source, "B": b.source, "alpha": alpha,
        "critical_z": zc, "joints": rows,
        "method": "z on the compliances x = 1/k, z = (x_B - x_A)/sqrt(var_A + var_B), "
                  "independent campaigns; verdict 'changed' when |z| > critical_z, the "
                  f"two-sided normal quantile at alpha/{len(common)} (Bonferroni), so the "
                  f"chance of any false alarm for an unchanged robot is at most {alpha:g}; "
                  "difference interval: k_B - k_A +- 1.96 sqrt(se_A^2 + se_B^2), se by the "
                  "delta method",
    }


def plot_comparison(result: dict, path: Path) -> Path:
    """Relative difference (k_B - k_A)/k_A per joint (%) with its 95 % interval."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = result["joints"]
    x = np.arange(len(rows))
    rel = np.array([100 * r["relative_difference"] for r in rows])
    lo = np.array([100 * r["ci95_difference_Nm_per_rad"][0] / r["k_A_Nm_per_rad"] for r in rows])
    hi = np.array([100 * r["ci95_difference_Nm_per_rad"][1] / r["k_A_Nm_per_rad"] for r in rows])
    colors = ["tab:red" if r["verdict"] == "changed" else "tab:gray" for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.axhline(0, color="black", lw=0.8)
    ax.errorbar(x, rel, yerr=[rel - lo, hi - rel], fmt="none", ecolor="black", capsize=4)
    ax.scatter(x, rel, c=colors, zorder=3)
    ax.set_xticks(x, [f"k{r['joint']}" for r in rows])
    ax.set_ylabel("(k_B - k_A) / k_A (%), 95 % interval")
    ax.set_title(f"{result['robot']}: B vs A (red: changed, alpha {result['alpha']:g})",
                 fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    from analysis.output_files import save_figure

    save_figure(fig, path, dpi=120)
    plt.close(fig)
    return path
