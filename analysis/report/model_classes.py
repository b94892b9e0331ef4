"""The report's tables of the model classes (results.json ``assumptions.model_classes``):
the candidates side by side and the chosen class's parameters with 95 % intervals."""

from __future__ import annotations

from analysis.report.document import Table
from analysis.report.formatting import sig


def model_class_blocks(record: dict | None) -> list:
    """[candidates table, chosen class's parameters table] (empty without a record)."""
    if not record:
        return []
    rows = []
    for c in record["candidates"]:
        if "error" in c:
            rows.append([c["model"], "-", "-", "-", "-", "-", f"not fitted: {c['error']}"])
            continue
        rows.append([c["model"], sig(c["chi2_nu"], 4), sig(c["heldout_chi2_nu"], 4),
                     sig(c["heldout_error_pct"], 3), sig(c["bic"], 6),
                     str(c["n_parameters"]),
                     "chosen" if c["model"] == record["chosen"] else ""])
    verdict = "accepted" if record["accepted"] else \
        f"refused: chi-square test below {record['misfit_level']:g}"
    out = [Table(f"Model classes ({record['asked']}): {record['rule']}; chosen "
                 f"{record['chosen']}, {verdict}",
                 ["model", "chi2/nu", "held-out chi2/nu", "held-out error %", "BIC",
                  "parameters", ""], rows, widths=[2.4, 1, 1.2, 1.1, 1.1, 0.9, 1.6])]
    chosen = next((c for c in record["candidates"] if c["model"] == record["chosen"]), None)
    if chosen and chosen.get("parameters"):
        prow = [[p["name"], f"{p['value']:.4g}", f"{p['se']:.2g}",
                 f"[{p['ci95'][0]:.4g}, {p['ci95'][1]:.4g}]", p["unit"]]
                for p in chosen["parameters"]]
        prow += [[f["parameter"], "fixed at 0", "-", "-", f["why"]] for f in chosen["fixed"]]
        out.append(Table(f"Parameters of {chosen['model']} beyond the joint springs (95 % "
                         "intervals, Gaussian)", ["parameter", "value", "se",
                                                  "95 % interval", "unit / why"],
                         prow, widths=[1.6, 1, 0.8, 1.8, 2.4]))
    return out
