"""z-scores of the exact fit's k at large N: (k - k_true) / se over seeded campaigns.

KR240-2 at its nominal stiffness, 10 tests per pose in its zones, forces of 1-2.5 kN
and moments of 100-300 N m in random directions, the default noise model's noise on
the displacements, the wrench and the joint angles (the large-import benchmark's
simulation, ``benchmarks/_large_csv.py``), identified in memory with ``exact`` (no
validation). Target (issue 22): over >= 20 seeds at each N, the mean z of every joint
within +-0.5 and its standard deviation within 0.8-1.25.

    PYTHONPATH=. python -m tests.quality.zscore_study [--sizes 10000 100000] [--seeds 20]

prints a Markdown table and one JSON line.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
from pathlib import Path

import numpy as np

from analysis.identification.estimate import identify
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.model.robots import load_robot

ROOT = Path(__file__).resolve().parents[2]


def _simulation():
    spec = importlib.util.spec_from_file_location("_large_csv",
                                                  ROOT / "benchmarks" / "_large_csv.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.simulated_tests


def zscores(n: int, seeds: int) -> np.ndarray:
    """(seeds, 6) z-scores of k for campaigns of n tests."""
    simulated = _simulation()
    robot = load_robot("kr240-2")
    out = np.empty((seeds, 6))
    for s in range(seeds):
        labels, q, w, d = simulated(n, seed=1000 + s)
        # a pose drawn at a joint limit may read just beyond it with encoder noise
        q = np.clip(q, robot.lower, robot.upper)
        tests = TestArrays(labels, q, w, d, np.ones(d.shape, bool), np.arange(n) + 2)
        res = identify(robot, tests, "exact", noise=NoiseModel(), validate=False)
        out[s] = (res.k - robot.nominal_stiffness) / res.se_k
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    ap.add_argument("--seeds", type=int, default=20)
    args = ap.parse_args(argv)
    t0 = time.process_time()
    print("| tests | mean z, k1..k6 | std z, k1..k6 |")
    print("| --- | --- | --- |")
    rows, ok = {}, True
    for n in args.sizes:
        z = zscores(n, args.seeds)
        mean, sd = z.mean(axis=0), z.std(axis=0, ddof=1)
        ok &= bool(np.all(np.abs(mean) <= 0.5) and np.all((sd >= 0.8) & (sd <= 1.25)))
        rows[n] = {"mean": np.round(mean, 3).tolist(), "std": np.round(sd, 3).tolist()}
        print(f"| {n} | {' '.join(f'{v:+.2f}' for v in mean)} | "
              f"{' '.join(f'{v:.2f}' for v in sd)} |", flush=True)
    print(json.dumps({"study": "zscore_large_n", "seeds": args.seeds, "results": rows,
                      "within_target": ok, "cpu_s": round(time.process_time() - t0, 1)}))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
