"""Benchmark: the 5-pose KR240-2 campaign on the simulated lab, end to end over loopback.

Runs the built-in protocol's plan (5 tests x 3 repeats) with ``campaign acquire --fake``
at several time scales s (default 25, 50, 100, 200), each ``--repeat`` times, in one
process, the scales interleaved. Wall time is modelled as
``T(s) = overhead + lab_time / s``: ``lab_time`` is the simulated robot's own time
(motions and settling, seconds of robot time), ``overhead`` what the software and the
loopback protocols add. The model is fitted by least squares to every run (not two
points), and its uncertainty is given two ways: the standard errors of the fit and the
spread (min..max) of the per-repeat fits. Residuals of the fit show whether the model
holds. The machine may be shared with other work: the spread says how much that moved
the figures.

Run: ``python benchmarks/bench_fake_campaign.py [--scales 25 50 100 200] [--repeat 3]``.
The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from _load import LoadWindow

from campaign.acquire.progress import QuietReporter
from campaign.acquire.session import AcquireOptions, acquire
from campaign.planning.planner import make_plan, write_plan
from campaign.protocol import load_protocol

PROTOCOL = Path(__file__).resolve().parents[1] / "protocols" / "kr240-2.toml"


def run(plan: Path, out: Path, scale: float) -> tuple[float, float]:
    """(wall s, CPU s of this process) of one fake campaign at time scale ``scale``."""
    c0, t0 = time.process_time(), time.perf_counter()
    outcome = acquire(plan, out, None, AcquireOptions(fake=True, assume_yes=True,
                                                      time_scale=scale),
                      QuietReporter(), say=lambda s: None)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    if outcome.status != "complete":
        raise SystemExit(f"campaign {outcome.status}: {outcome.reason}")
    return wall, cpu


def fit(scales: np.ndarray, walls: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least squares of wall = overhead + lab_time / s: (coef, standard errors, residuals)."""
    A = np.column_stack([np.ones_like(scales), 1.0 / scales])
    coef, *_ = np.linalg.lstsq(A, walls, rcond=None)
    resid = walls - A @ coef
    dof = max(len(walls) - 2, 1)
    cov = np.linalg.inv(A.T @ A) * float(resid @ resid) / dof
    return coef, np.sqrt(np.diag(cov)), resid


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scales", type=float, nargs="+", default=[25.0, 50.0, 100.0, 200.0])
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    scales = sorted(set(args.scales))
    if len(scales) < 3:
        raise SystemExit("give at least three time scales (two points determine any line)")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        plan = Path(tmp) / "plan"
        write_plan(make_plan(load_protocol(PROTOCOL)), plan, figure=False)
        for r in range(args.repeat):
            for s in scales:
                wall, cpu = run(plan, Path(tmp) / f"run_{r}_{s:g}", s)
                rows.append((r, s, wall, cpu))
                print(f"repeat {r + 1}, scale {s:g}: {wall:.2f} s wall, {cpu:.2f} s CPU",
                      flush=True)
    data = np.array(rows)
    coef, se, resid = fit(data[:, 1], data[:, 2])
    per_repeat = np.array([fit(data[data[:, 0] == r, 1], data[data[:, 0] == r, 2])[0]
                           for r in range(args.repeat)])
    overhead, lab_time = coef
    print(f"5 tests x 3 repeats at scales {', '.join(f'{s:g}' for s in scales)}, "
          f"{args.repeat} runs each ({len(rows)} runs)")
    print(f"simulated robot time (motions, settling): {lab_time:.1f} +- {se[1]:.1f} s "
          f"(per-repeat fits {per_repeat[:, 1].min():.1f}..{per_repeat[:, 1].max():.1f})")
    print(f"software and loopback overhead: {overhead:.2f} +- {se[0]:.2f} s "
          f"(per-repeat fits {per_repeat[:, 0].min():.2f}..{per_repeat[:, 0].max():.2f})")
    print(f"largest |residual| of the fit: {np.max(np.abs(resid)):.2f} s; CPU of this "
          f"process per run {data[:, 3].min():.2f}..{data[:, 3].max():.2f} s")
    walls = {f"{s:g}": [round(float(v), 3) for v in data[data[:, 1] == s, 2]] for s in scales}
    load.emit({
        "benchmark": "fake_campaign", "scales": scales, "repeat": args.repeat,
        "wall_s_by_scale": walls,
        "lab_time_s": round(float(lab_time), 2), "lab_time_se_s": round(float(se[1]), 2),
        "lab_time_per_repeat_s": [round(float(v), 2) for v in per_repeat[:, 1]],
        "overhead_s": round(float(overhead), 3), "overhead_se_s": round(float(se[0]), 3),
        "overhead_per_repeat_s": [round(float(v), 3) for v in per_repeat[:, 0]],
        "max_abs_residual_s": round(float(np.max(np.abs(resid))), 3),
        "cpu_s_per_run_range": [round(float(data[:, 3].min()), 3),
                                round(float(data[:, 3].max()), 3)],
        "runs": len(rows),
        "baseline": "none: the model's two terms (overhead, lab time / scale)",
        "timing": "wall time (time.perf_counter) of each whole campaign in this process, "
                  "scales interleaved within each repeat",
    })


if __name__ == "__main__":
    main()
