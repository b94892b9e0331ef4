"""The report's history section: this campaign against the robot's earlier ones.

Blocks of :mod:`analysis.report.document` (formatted once, shown alike in HTML and
PDF): a table of the robot's campaigns in the ledger with this one (stiffness in
kN m/rad, whether each is compared and why not), and the drift test of the latest
comparable campaign against the reference (:func:`campaign.jobs.history.check_robot`).
"""

from __future__ import annotations

from analysis.report.document import Paragraph, Table
from campaign.ledger.entry import LedgerEntry
from campaign.ledger.store import StoredCampaign


def _k(v) -> str:
    return "-" if v is None else f"{v / 1e3:.1f}"


def history_blocks(entry: LedgerEntry, earlier: list[StoredCampaign], min_change: float,
                   alpha: float) -> list:
    """The section's blocks for ``entry`` (this campaign) and the ledger's ``earlier``
    records of the same robot."""
    from campaign.jobs.history import check_robot, robot_history

    if not earlier:
        return [Paragraph(f"First campaign of robot {entry.robot_id} in the ledger: nothing "
                          "to compare with yet.", "note")]
    this = StoredCampaign(0, "", entry)
    records = sorted([*earlier, this], key=lambda r: (r.entry.campaign_date, r.id or 1e18))
    hist = robot_history(records)
    alarms, summary = check_robot(records, min_change, alpha)
    rows, marked = [], []
    for r in records:
        e = r.entry
        status = ("reference" if e.report_id == hist.reference
                  else f"left out: {hist.reasons[e.report_id]}" if e.report_id in hist.reasons
                  else "compared")
        rows.append([e.campaign_date[:10], e.report_id + (" (this)" if r is this else ""),
                     *[_k(v) for v in e.k], status])
        marked.append(False)
    blocks = [Table(f"Campaigns of robot {entry.robot_id}",
                    ["date", "report", *[f"k{j} (kN m/rad)" for j in range(1, 7)], "status"],
                    rows, marked, caption="Every campaign of this robot in the fleet ledger, "
                    "oldest first; campaigns with another estimator, other joints, another "
                    "model class or accepted despite a refusal are left out of the test.")]
    if summary["tests"]:
        test_rows = [[str(t["joint"]), f"{t['change_percent']:+.2f}",
                      f"[{t['interval'][0]:.2f}, {t['interval'][1]:.2f}]",
                      "DROPPED" if t["alarm"] else "no drop shown"] for t in summary["tests"]]
        blocks.append(Table(
            f"Campaign {summary['latest']} against the reference {summary['reference']}",
            ["joint", "change (%)", "interval (%)", "verdict"], test_rows,
            [t["alarm"] for t in summary["tests"]],
            caption=f"Change of k = k/k_ref - 1; 'DROPPED' when the one-sided bound at the "
            f"joint's Holm level (family level {alpha:g} over the joints) is below "
            f"-{100 * min_change:g} %; the interval's upper end is that bound."))
    blocks.append(Paragraph(
        "; ".join(f"ALARM joint {a['joint']}: {a['change_percent']:+.2f} % ({a['test']})"
                  for a in alarms) if alarms else
        f"No joint of robot {entry.robot_id} shows a drop of more than "
        f"{100 * min_change:g} %.", "warning" if alarms else "verdict"))
    return blocks
