"""Benchmark: ``campaign compensate``'s computation on a 10 000-point path, batched vs per point.

The batched path (:func:`analysis.kinetostatics.path_compensation.compensate_path`:
limits and singularity checks, predicted deflection with its covariance,
Newton compensation on the equilibrium, uncertainty after compensation) runs
on all points at once; the baseline calls the same function one point at a
time for a sample of points (the same numpy code with batch size 1, the best
per-point implementation we have). Outputs are compared on the sample.
Ends with one JSON line.

Run: ``python benchmarks/bench_compensate.py [--points 10000] [--sample 300]``
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from analysis.kinetostatics.path_compensation import compensate_path
from analysis.model.robots import load_robot


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--sample", type=int, default=300)
    args = parser.parse_args()
    robot = load_robot("kr240-2")
    k = robot.nominal_stiffness
    cov = np.diag((0.01 / k) ** 2)  # 1 % compliance uncertainty per joint
    t = np.linspace(0.0, 1.0, args.points)[:, None]
    a = np.radians([0, 30, -200, 40, 50, 30.0])
    b = np.radians([30, 60, -190, 60, 40, -20.0])
    q = a + (b - a) * t + np.radians(2.0) * np.sin(40 * np.pi * t)  # a wavy machining path
    w = np.array([0, 1000.0, -1500.0, 100.0, 50.0, 0.0])
    lines = np.arange(args.points) + 2
    compensate_path(robot, q[:10], k, w, cov, lines[:10], "path")  # warm-up (imports)
    t0, c0 = time.perf_counter(), time.process_time()
    batched = compensate_path(robot, q, k, w, cov, lines, "path")
    t_batch, c_batch = time.perf_counter() - t0, time.process_time() - c0
    idx = np.linspace(0, args.points - 1, args.sample).astype(int)
    q_loop, d_loop = [], []
    t0, c0 = time.perf_counter(), time.process_time()
    for i in idx:
        one = compensate_path(robot, q[i:i + 1], k, w, cov, lines[i:i + 1], "path")
        q_loop.append(one.comp.q_cmd[0])
        d_loop.append(one.before.screw[0])
    t_loop, c_loop = time.perf_counter() - t0, time.process_time() - c0
    dq_cmd = float(np.abs(np.array(q_loop) - batched.comp.q_cmd[idx]).max())
    dd = float(np.abs(np.array(d_loop) - batched.before.screw[idx]).max())
    res = float(np.abs(batched.comp.residual).max())
    rate_b, rate_l = args.points / t_batch, args.sample / t_loop
    print(f"batched: {args.points} points in {t_batch:.2f} s ({rate_b:.0f} points/s)")
    print(f"per-point loop: {args.sample} points in {t_loop:.2f} s ({rate_l:.0f} points/s)")
    print(f"max |q_cmd batched - loop| = {dq_cmd:.2e} rad, max |deflection diff| = {dd:.2e}; "
          f"max residual {res:.2e}")
    print(json.dumps({"benchmark": "compensate", "points": args.points,
                      "batched_s": round(t_batch, 4), "batched_points_per_s": round(rate_b, 1),
                      "loop_points_per_s": round(rate_l, 1), "ratio": round(rate_b / rate_l, 2),
                      "max_q_cmd_difference_rad": dq_cmd, "max_deflection_difference": dd,
                      "max_residual": res, "sample": args.sample,
                      "batched_cpu_s": round(c_batch, 4),
                      "loop_cpu_points_per_s": round(args.sample / c_loop, 1),
                      "ratio_cpu": round((args.points / c_batch) / (args.sample / c_loop), 2),
                      "baseline": "the same function called point by point on a sample "
                                  "(batch size 1), per-point rate",
                      "timing": "wall time (time.perf_counter) and CPU time "
                                "(time.process_time), one run per side after a warm-up, "
                                "BLAS threads left at their default"}))


if __name__ == "__main__":
    main()
