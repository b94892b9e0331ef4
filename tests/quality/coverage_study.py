"""Coverage table of the 95 % intervals of k, every Gaussian method, nominal and 2x loads.

Seeded Monte-Carlo on the robot file the tests write (``_own_robot.py``: a 6R arm the
project ships no model of), 5 poses x 3 load cases, tracker 30 um / 40 urad per
component, F/T 0.5 N + 0.5 % of reading (``_coverage.NOISE``). With 1000 campaigns the
binomial standard error of a 95 % coverage is 0.69 %, so 95 +- 3 % is resolved.

    PYTHONPATH=. python -m tests.quality.coverage_study [--trials 1000] [--seed 3]

prints a Markdown table (the one in docs/identification.md) and one JSON line.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from tests.quality._coverage import campaign_setup, coverage
from tests.quality._own_robot import write_protocol

METHODS = ("ols", "wls", "exact")
SCALES = (1.0, 2.0)


def study(trials: int, seed: int) -> dict:
    """{method: {scale: (coverage (6,), campaigns given)}}."""
    with tempfile.TemporaryDirectory() as tmp:
        robot, q, W, k = campaign_setup(write_protocol(Path(tmp)))
        return {m: {s: coverage(robot, q, W, k, m, s, trials, seed=seed) for s in SCALES}
                for m in METHODS}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=3)
    args = ap.parse_args(argv)
    t0 = time.process_time()
    res = study(args.trials, args.seed)
    print("| method | nominal loads: coverage k1..k6 (%) | twice the loads (%) |")
    print("| --- | --- | --- |")
    out = {}
    for m, by_scale in res.items():
        cells = []
        for s, (cov, given) in by_scale.items():
            refused = args.trials - given
            cells.append(" ".join(f"{100 * c:.1f}" for c in cov)
                         + (f" ({refused} refused)" if refused else ""))
            out[f"{m}_x{s:g}"] = {"coverage": [round(float(c), 4) for c in cov],
                                  "given": given}
        print(f"| `{m}` | {cells[0]} | {cells[1]} |")
    worst = max(abs(c - 0.95) for v in out.values() for c in v["coverage"])
    print(json.dumps({"study": "coverage", "trials": args.trials, "seed": args.seed,
                      "results": out, "worst_deviation_from_95": round(worst, 4),
                      "within_3_percent": worst <= 0.03,
                      "cpu_s": round(time.process_time() - t0, 1)}))
    return 0 if worst <= 0.03 else 1


if __name__ == "__main__":
    sys.exit(main())
