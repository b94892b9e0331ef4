"""Benchmark: ``history list`` and ``history trend`` of one robot in a large SQLite ledger.

A ledger of ``--robots`` robots x ``--campaigns`` campaigns (default 10,000 x 20 =
200,000 records) is built at the head schema in a temporary directory (one bulk
insert; each record has six stiffnesses drawn around the KR240-2's Table 2 values,
their 95 % intervals and a 6 x 6 compliance covariance, as a real record). Then,
for ``--repeat`` robots drawn at random, the jobs behind the two commands
(:func:`campaign.jobs.history.listing` and :func:`~campaign.jobs.history.trend`),
each called as the command calls it: open the ledger (engine, schema check),
query, decode, close. Wall time of each call (``time.perf_counter``); the figures
are the worst and the median over the robots. The answers are checked: each
robot's 20 campaigns, oldest first, with the stiffness inserted.

Target (issue 33): list and trend of one robot < 0.5 s on SQLite.

Run: ``python benchmarks/bench_ledger.py [--robots 10000] [--campaigns 20]
[--repeat 5]``. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np
from _load import LoadWindow

K_TABLE2 = np.array([1409800.0, 400760.0, 935280.0, 360000.0, 370000.0, 380000.0])


def build(db: Path, robots: int, campaigns: int, seed: int = 1) -> dict[str, list[float]]:
    """Write the ledger; returns robot 0's first campaign's k (for the check)."""
    from sqlalchemy import insert

    from campaign.ledger.database import open_ledger
    from campaign.ledger.schema import CampaignRecord

    rng = np.random.default_rng(seed)
    engine = open_ledger(str(db), create=True)
    rel = 0.004
    cov = json.dumps((np.diag((rel / K_TABLE2) ** 2)).tolist())
    instruments = json.dumps([{"role": "robot", "model": "KR240-2", "serial": None,
                               "calibration_date": "2026-01-15", "calibration_due": None,
                               "certificate": None}])
    first = {}
    with engine.begin() as conn:
        for r in range(robots):
            rid = f"R{r:05d}"
            ks = K_TABLE2 * np.exp(rng.normal(0, rel, (campaigns, 6)))
            rows = []
            for c in range(campaigns):
                k = ks[c].tolist()
                if c == 0:
                    first[rid] = k
                ci = [[v * (1 - 1.96 * rel), v * (1 + 1.96 * rel)] for v in k]
                rows.append({
                    "report_id": f"RPT-{r:08x}{c:08x}", "robot_id": rid,
                    "robot_model": "KUKA KR240-2",
                    "campaign_date": f"{2020 + c // 12:04d}-{c % 12 + 1:02d}-01T00:00:00+00:00",
                    "recorded_utc": "2026-12-07T00:00:00+00:00", "estimator": "exact",
                    "model_class": "KUKA KR240-2; geometry 0123456789abcdef",
                    "joints_identified": "[1, 2, 3, 4, 5, 6]", "k_Nm_per_rad": json.dumps(k),
                    "ci95_Nm_per_rad": json.dumps(ci), "covariance_of_compliance": cov,
                    "chi2_reduced": 1.0, "dof": 84, "condition_number": 2.4,
                    "accepted_despite_refusal": False,
                    "tool": '{"xyz_mm": [0, 0, 0], "rpy_deg": [0, 0, 0]}', "payload_kg": 0.0,
                    "instruments": instruments, "results_sha256": "0" * 64,
                    "tests_sha256": "1" * 64, "plan_sha256": "2" * 64,
                    "protocol_sha256": "3" * 64, "source_dir": f"/fleet/{rid}/{c}",
                    "supersedes": None, "temperatures": None, "software_version": "0.1.0"})
            conn.execute(insert(CampaignRecord), rows)
    engine.dispose()
    return first


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--robots", type=int, default=10_000)
    parser.add_argument("--campaigns", type=int, default=20)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    load = LoadWindow()
    from campaign.jobs.history import listing, trend

    with tempfile.TemporaryDirectory() as tmp:
        db = Path(tmp) / "fleet.sqlite"
        t0 = time.perf_counter()
        first = build(db, args.robots, args.campaigns)
        build_s = time.perf_counter() - t0
        rng = np.random.default_rng(7)
        picks = [f"R{int(r):05d}" for r in rng.integers(0, args.robots, args.repeat)]
        times = {"list": [], "trend": []}
        ok = True
        for rid in picks:
            t = time.perf_counter()
            got = listing(str(db), rid)
            times["list"].append(time.perf_counter() - t)
            t = time.perf_counter()
            tr = trend(str(db), rid)
            times["trend"].append(time.perf_counter() - t)
            dates = [c["date"] for c in tr.campaigns]
            ok &= (len(got.campaigns) == args.campaigns == len(tr.campaigns)
                   and dates == sorted(dates) and tr.campaigns[0]["k_Nm_per_rad"] == first[rid]
                   and all(c["robot"] == rid for c in got.campaigns))
        size_MB = db.stat().st_size / 2**20
    figures = {"benchmark": "ledger", "backend": "sqlite", "robots": args.robots,
               "campaigns_per_robot": args.campaigns,
               "records": args.robots * args.campaigns, "file_MB": round(size_MB, 1),
               "build_s": round(build_s, 1), "repeat": args.repeat,
               "list_s_max": round(max(times["list"]), 4),
               "list_s_median": round(statistics.median(times["list"]), 4),
               "trend_s_max": round(max(times["trend"]), 4),
               "trend_s_median": round(statistics.median(times["trend"]), 4),
               "answers_checked": bool(ok),
               "timing": "wall time per call (open, query, decode, close)"}
    for key in ("list", "trend"):
        print(f"{key}: " + ", ".join(f"{v:.4f}" for v in times[key]) + " s", flush=True)
    load.emit(figures)


if __name__ == "__main__":
    main()
