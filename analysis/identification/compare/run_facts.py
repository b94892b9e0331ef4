"""What identifies one side of a comparison: its robot, campaign, measurement date and
report ID, read from its results.json and the run's metadata.json beside it."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from analysis.text_format import utc_text


@dataclass
class RunFacts:
    """What identifies one side of the comparison."""

    label: str
    results: str
    robot: str
    campaign: str
    started: str
    report_id: str
    simulated: bool


def run_facts(label: str, results_path: str | Path) -> RunFacts:
    """Facts of a results.json and of the run's metadata.json beside it (when there)."""
    rp = Path(results_path)
    doc = json.loads(rp.read_text(encoding="utf-8"))
    meta = {}
    for cand in (rp.parent.parent / "metadata.json", rp.parent / "metadata.json"):
        if cand.is_file():
            try:
                meta = json.loads(cand.read_text(encoding="utf-8"))
            except (OSError, ValueError):
                meta = {}
            break
    return RunFacts(label, str(rp), str(doc.get("robot", "-")),
                    str(meta.get("campaign") or ""), utc_text(meta.get("started_utc")),
                    str(doc.get("report_id") or ""),
                    bool(meta.get("fake")) or bool(meta.get("fake_lab")))
