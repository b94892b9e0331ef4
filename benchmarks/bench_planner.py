"""Benchmark of the planner: 1e4 candidates to 5-20 pose designs on the KR240-2.

Run: ``python benchmarks/bench_planner.py``. Prints the time of each stage, the
throughput in candidates per second and, in the same run, the ratio against a
naive baseline (per-candidate Python loops: one Jacobian, one 1/kappa_F, one
K_C check and one determinant at a time; greedy selection without exchange).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from analysis.identification.linear_model import design_block
from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.stiffness import kc_influence
from analysis.model.kinematics import jacobian
from campaign.design import information, scaled_blocks
from campaign.planner import make_plan
from campaign.protocol import load_protocol

ROOT = Path(__file__).resolve().parents[1]


def naive_plan(plan, n: int, subset: int) -> float:
    """Seconds per candidate of a naive planner, measured on ``subset`` candidates."""
    protocol, robot = plan.protocol, plan.robot
    q = plan.candidates.q[:subset]
    wrenches = protocol.wrenches()
    th = protocol.thresholds
    start = time.perf_counter()
    tests = []
    for qi in q:
        J = jacobian(robot, qi)
        if inverse_condition(normalized_jacobian(J, plan.length)) < th.min_inv_kappa_F:
            continue
        for w in wrenches:
            v_p, v_r = kc_influence(robot, qi, plan.k_prior, w)
            if v_p <= th.max_v_p and v_r <= np.radians(th.max_v_r_deg):
                B = design_block(J, w) / plan.sigma[:, None] / plan.k_prior
                tests.append(B.T @ B)
    M = 1e-9 * np.eye(6)
    used: set[int] = set()
    for _ in range(n):
        best, best_val = -1, -np.inf
        for i, F in enumerate(tests):
            if i in used:
                continue
            val = np.linalg.slogdet(M + F)[1]
            if val > best_val:
                best, best_val = i, val
        used.add(best)
        M = M + tests[best]
    return (time.perf_counter() - start) / len(q)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--candidates", type=int, default=10000)
    parser.add_argument("--naive-subset", type=int, default=500)
    args = parser.parse_args()
    protocol = load_protocol(ROOT / "protocols" / "kr240-2.toml")
    make_plan(protocol, candidates=200)  # warm-up (imports, caches)
    print(f"KR240-2, {args.candidates} candidates x {len(protocol.load_cases)} load cases")
    best = np.inf
    for n in (5, 10, 20):
        for strategy in ("d-optimal", "e-optimal"):
            t0 = time.perf_counter()
            plan = make_plan(protocol, strategy, seed=0, candidates=args.candidates, tests=n)
            dt = time.perf_counter() - t0
            best = min(best, dt / args.candidates) if n == 5 and strategy == "d-optimal" else best
            print(f"  {strategy:9s} n={n:2d}: {dt:6.2f} s, "
                  f"{args.candidates / dt:8.0f} candidates/s")
    cand = plan.candidates
    t0 = time.perf_counter()
    pose, case = np.nonzero(cand.valid)
    information(scaled_blocks(cand.J[pose], protocol.wrenches()[case], plan.sigma, plan.k_prior))
    print(f"  information matrices of {pose.size} tests: {time.perf_counter() - t0:.3f} s")
    naive = naive_plan(plan, 5, args.naive_subset)
    print(f"naive baseline (per-candidate loops, greedy only), measured on "
          f"{args.naive_subset} candidates: {1 / naive:8.0f} candidates/s")
    print(f"speed-up of the batched planner (n=5, d-optimal, with exchange): "
          f"{naive / best:.1f}x")


if __name__ == "__main__":
    main()
