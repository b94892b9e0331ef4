"""The report of ``campaign compare A B`` (HTML and PDF, in the style of the analysis report).

Both runs are named with their robot, campaign, date and report ID; per joint the
difference k_B - k_A with its interval at the verdict's level (1 - alpha/m, the
Bonferroni level the verdict uses, so an interval excluding 0 is exactly a
"changed" verdict), the z score and the verdict; a plot of the relative
differences naming A and B.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.compare.run_facts import RunFacts
from analysis.report.document import Figure, Paragraph, Report, Section, Table, Trace
from analysis.report.formatting import fixed, k_kNm, percent


def level_intervals(result: dict) -> list[tuple[float, float]]:
    """(lo, hi) of k_B - k_A (N m/rad) at the verdict's level: the comparison's own
    ``interval_difference_Nm_per_rad`` when it gives it, else +- critical_z sqrt(se_A^2 +
    se_B^2)."""
    zc = float(result["critical_z"])
    out = []
    for r in result["joints"]:
        if "interval_difference_Nm_per_rad" in r:
            lo, hi = r["interval_difference_Nm_per_rad"]
            out.append((float(lo), float(hi)))
            continue
        half = zc * float(np.hypot(r["se_A_Nm_per_rad"], r["se_B_Nm_per_rad"]))
        out.append((r["difference_Nm_per_rad"] - half, r["difference_Nm_per_rad"] + half))
    return out


def comparison_figure(result: dict, a: RunFacts, b: RunFacts) -> Figure:
    """(k_B - k_A) / k_A (%) per joint with the interval at the verdict's level."""
    from analysis.report import figures

    fig, ax = figures._new(legend_below=True)
    rows = result["joints"]
    x = np.arange(len(rows))
    ka = np.array([r["k_A_Nm_per_rad"] for r in rows])
    rel = np.array([100 * r["relative_difference"] for r in rows])
    iv = np.array(level_intervals(result))
    lo, hi = 100 * iv[:, 0] / ka, 100 * iv[:, 1] / ka
    changed = np.array([r["verdict"] == "changed" for r in rows])
    ax.axhline(0, color="black", lw=0.8)
    ax.errorbar(x, rel, yerr=[rel - lo, hi - rel], fmt="none", ecolor="black", capsize=4)
    if (~changed).any():
        ax.plot(x[~changed], rel[~changed], "o", color="tab:gray",
                label="no evidence of change")
    if changed.any():
        ax.plot(x[changed], rel[changed], "o", color="tab:red", label="changed")
    ax.set_xticks(x, [f"$k_{r['joint']}$" for r in rows])
    level = 1 - result["alpha"] / len(rows)
    ax.set_ylabel(f"$(k_B - k_A)/k_A$ (%), {100 * level:.3g} % interval")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2,
              frameon=False)
    figures._title(ax, "\n".join(f"{f.label}: {f.campaign or f.results} ({f.started[:10]}, "
                                  f"{f.robot}{', simulated' if f.simulated else ''})"
                                  for f in (a, b)), fontsize=7.5)
    return figures._png(fig, "comparison", "Relative difference of each k, B against A, with "
                        f"its interval at the verdict's level ({100 * level:.3g} %: "
                        f"alpha {result['alpha']:g} shared over {len(rows)} joints); red: "
                        "changed.")


def simulated_text(a: RunFacts, b: RunFacts) -> str:
    """The SIMULATED DATA banner naming the simulated run(s) ("" when neither is)."""
    sim = [f for f in (a, b) if f.simulated]
    if not sim:
        return ""
    which = ("both runs (A and B) came" if len(sim) == 2 else
             f"run {sim[0].label} ({sim[0].campaign or sim[0].results}) came")
    return (f"SIMULATED DATA \u2014 {which} from the simulated lab, not from a measurement "
            "of a real robot")


def build_compare_report(result: dict, a: RunFacts, b: RunFacts) -> Report:
    """The comparison as a :class:`Report` (verdict first, both runs named)."""
    from analysis.report.traceability import software_text, utc_now_text

    rows_j = result["joints"]
    changed = [f"k{r['joint']}" for r in rows_j if r["verdict"] == "changed"]
    level = 1 - result["alpha"] / len(rows_j)
    verdict = (Paragraph("Changed: " + ", ".join(changed) + f" (|z| > "
                         f"{result['critical_z']:.3f}; false-alarm rate {result['alpha']:g} "
                         "over all joints compared).", "refusal") if changed else
               Paragraph(f"No evidence of change in any of the {len(rows_j)} joints compared "
                         f"(|z| <= {result['critical_z']:.3f}; false-alarm rate "
                         f"{result['alpha']:g} over all joints).", "verdict"))
    runs = Table("Runs compared", ["", "robot", "campaign", "measured", "report ID",
                                   "results"],
                 [[f.label, f.robot, f.campaign or "-", f.started, f.report_id or "-",
                   f.results] for f in (a, b)], widths=[0.3, 1.1, 1.6, 1.2, 1.1, 2.4])
    iv = level_intervals(result)
    rows = []
    marked = []
    for r, (lo, hi) in zip(rows_j, iv, strict=True):
        rows.append([f"k{r['joint']}", k_kNm(r["k_A_Nm_per_rad"]), k_kNm(r["k_B_Nm_per_rad"]),
                     percent(r["relative_difference"]),
                     f"[{fixed(lo / 1e3, 3)}, {fixed(hi / 1e3, 3)}]", fixed(r["z"], 2),
                     r["verdict"] + (" (borderline)" if "note" in r else "")])
        marked.append(r["verdict"] == "changed")
    table = Table("Difference per joint", [
        "joint", "k_A (kN m/rad)", "k_B (kN m/rad)", "k_B/k_A - 1 (%)",
        f"k_B - k_A, {100 * level:.3g} % interval (kN m/rad)", "z", "verdict"], rows, marked,
        caption=f"Interval at the verdict's level (1 - alpha/m = {100 * level:.4g} %): it "
        "excludes 0 when the verdict is 'changed' (borderline: the interval, by the delta "
        "method on k, and the z test, on the compliances, disagree). "
        + "; ".join(result.get("notes", [])) + " " + result.get("method", ""),
        widths=[0.6, 1.1, 1.1, 1.0, 1.9, 0.6, 1.5])
    facts = Paragraph(f"Robot: {a.robot} \u00b7 A: {a.campaign or a.results}, measured "
                      f"{a.started} \u00b7 B: {b.campaign or b.results}, measured "
                      f"{b.started}", "facts")
    section = Section("Comparison", [facts, verdict, table, runs,
                                     comparison_figure(result, a, b)])
    title = f"Joint stiffness of {a.robot}: B against A"
    return Report(title, f"A: {a.results} \u00b7 B: {b.results}", [section],
                  simulated=a.simulated or b.simulated,
                  simulated_text=simulated_text(a, b),
                  trace=Trace("", utc_now_text(), software_text()))
