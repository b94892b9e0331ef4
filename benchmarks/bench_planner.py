"""Benchmark of the planner on the KR240-2: batched vs the same algorithm run per candidate.

Work measured: draw N candidate poses, evaluate them (limits, 1/kappa_F, v_p
and v_r per load case), build the information matrix of every valid test and
choose the design (greedy + exchange, same screening).

* Batched: ``make_plan`` (blocks of poses, BLAS pinned to one thread, J reused
  across load cases).
* Baseline: the same algorithm with per-candidate evaluation, made as fast as
  we could write it (:func:`per_candidate_plan`): per pose one Pinocchio frame
  Jacobian and frame kinematic Hessian at P (K_C of each load case from it),
  1/kappa_F and the two deflections per load case through LAPACK ``dgesv``
  called directly, the indices on floats, one information matrix per test,
  then the same ``greedy_exchange`` (greedy plus exchange, same screening, the
  same minimum joint-space separation between poses). Run on the same
  candidates; the two designs must be equal. ``make_plan`` also draws the
  random zone designs its summary compares with (part of its time), which
  the baseline skips: the ratio is, if anything, low.

Both sides single-threaded (threadpoolctl), CPU time (``time.process_time``)
and wall time, best of ``--repeat`` runs, interleaved. Batched throughput is
also reported at 1e4 and 1e5 candidates to show it is linear.

Run: ``python benchmarks/bench_planner.py [--baseline-candidates 2000] [--repeat 2]``
The last line printed is one JSON object with the figures.
"""

from __future__ import annotations

import argparse
import time
from math import sqrt
from pathlib import Path

import numpy as np
import pinocchio as pin
from _load import LoadWindow
from scipy.linalg.lapack import dgesv
from threadpoolctl import threadpool_limits

from campaign.planning.candidates import sample
from campaign.planning.design import greedy_exchange
from campaign.planning.planner import _expand, make_plan
from campaign.planning.separation import Separation
from campaign.protocol import DEG, load_protocol
from campaign.protocol_robot import (
    characteristic_length,
    prior_stiffness,
    protocol_robot,
    sampling_boxes,
)

ROOT = Path(__file__).resolve().parents[1]
LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def per_candidate_plan(protocol, candidates: int, seed: int = 0):
    """(pose, case) rows of the D-optimal design, every candidate evaluated on its own.

    Made as fast as we could write it: Pinocchio's frame Jacobian and frame
    kinematic Hessian at P (one ``Data``, LOCAL_WORLD_ALIGNED; K_C of every load
    case from the one Hessian), LAPACK ``dgesv`` called directly for J_N^-1 and
    each deflection, the indices on Python floats, and each test's information
    as ``G o (t t^T)`` with ``G = J^T diag(sigma^-2) J`` once per pose and
    ``t = J^T w / k0`` per load case.
    """
    robot = protocol_robot(protocol)
    k, sigma = prior_stiffness(protocol, robot), protocol.measurement_sigma()
    length = characteristic_length(protocol, robot)
    q, _ = sample(sampling_boxes(protocol, robot), candidates, seed)
    th, wrenches = protocol.thresholds, protocol.wrenches()
    margin = protocol.safety.joint_margin_deg * DEG
    lo, hi = robot.lower + margin - 1e-12, robot.upper - margin + 1e-12
    model, data, tip = robot.model, robot.model.createData(), robot.tip_frame
    scale = np.array([1.0 / length] * 3 + [1.0] * 3)[:, None]
    Kt, inv_k, s2 = np.diag(k), 1.0 / np.asarray(k, dtype=float), 1.0 / sigma ** 2
    eye = np.asfortranarray(np.eye(6))
    max_v_p, max_v_r, min_inv_kappa = th.max_v_p, th.max_v_r_deg * DEG, th.min_inv_kappa_F
    every = protocol.loads.selection == "all"
    tests, F = [], []
    for i, qi in enumerate(q):
        if not ((qi >= lo).all() and (qi <= hi).all()):
            continue
        pin.computeJointJacobians(model, data, qi)
        J = pin.getFrameJacobian(model, data, tip, LWA)
        JN = scale * J
        JN_inv, singular = dgesv(JN, eye)[2:]
        if singular or 6.0 / sqrt(np.vdot(JN, JN) * np.vdot(JN_inv, JN_inv)) < min_inv_kappa:
            continue
        pin.computeJointKinematicHessians(model, data)
        H = pin.getFrameKinematicHessian(model, data, tip, LWA)
        G = (J.T * s2).dot(J)
        ok, ts = [], []
        for w in wrenches:
            tau = w.dot(J)
            dk = J.dot(dgesv((Kt - H.dot(w)).T, tau)[2]).tolist()
            dn = J.dot(tau * inv_k).tolist()
            a = sqrt(dk[0] * dk[0] + dk[1] * dk[1] + dk[2] * dk[2])
            b = sqrt(dn[0] * dn[0] + dn[1] * dn[1] + dn[2] * dn[2])
            v_p = abs(a - b) / max(a, b) if max(a, b) > 0 else 0.0
            v_r = max(abs(dk[3] - dn[3]), abs(dk[4] - dn[4]), abs(dk[5] - dn[5]))
            ok.append(v_p <= max_v_p and v_r <= max_v_r)
            ts.append(tau * inv_k)
        if every:
            if all(ok):
                T = np.array(ts)
                tests.append((i, -1))
                F.append(G * T.T.dot(T))
        else:
            for c, good in enumerate(ok):
                if good:
                    tests.append((i, c))
                    F.append(G * np.outer(ts[c], ts[c]))
    pose, case = (np.array(v, dtype=int) for v in zip(*tests, strict=True))
    # the same minimum joint-space separation between chosen poses as make_plan
    sep = Separation(q[pose], pose, protocol.thresholds.min_pose_separation_deg * DEG)
    picks = greedy_exchange(np.array(F), pose, protocol.campaign.tests, kind="d", sep=sep)
    return _expand(pose[picks], case[picks], len(wrenches))


def timed(fn):
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.process_time() - c0, time.perf_counter() - t0, out


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline-candidates", type=int, default=2000)
    parser.add_argument("--sizes", type=int, nargs="+", default=[10000, 100000])
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    protocol = load_protocol(ROOT / "protocols" / "kr240-2.toml")
    make_plan(protocol, candidates=200)  # warm-up (imports, caches)
    n0 = args.baseline_candidates
    fig = {"batched_cpu": np.inf, "batched_wall": np.inf, "loop_cpu": np.inf, "loop_wall": np.inf}
    with threadpool_limits(limits=1):
        for _ in range(args.repeat):
            c, t, plan = timed(lambda: make_plan(protocol, "d-optimal", seed=0, candidates=n0))
            fig["batched_cpu"], fig["batched_wall"] = min(fig["batched_cpu"], c), min(
                fig["batched_wall"], t)
            c, t, rows = timed(lambda: per_candidate_plan(protocol, n0))
            fig["loop_cpu"], fig["loop_wall"] = min(fig["loop_cpu"], c), min(fig["loop_wall"], t)
        same = (np.array_equal(rows[0], plan.chosen.pose)
                and np.array_equal(rows[1], plan.chosen.case))
        if not same:
            raise SystemExit(f"designs differ: batched {plan.chosen.pose.tolist()} "
                             f"vs per-candidate {rows[0].tolist()}")
        sizes = {}
        for n in args.sizes:
            best = min(timed(lambda n=n: make_plan(protocol, "d-optimal", seed=0,
                                                   candidates=n))[0]
                       for _ in range(args.repeat))
            sizes[n] = best / n * 1e6
    us = {key: v / n0 * 1e6 for key, v in fig.items()}
    print(f"KR240-2, {len(protocol.load_cases)} load cases, D-optimal, "
          f"{protocol.campaign.tests} tests; single-threaded, best of {args.repeat}, interleaved")
    print(f"on {n0} candidates: batched {us['batched_cpu']:.1f} us CPU/candidate, "
          f"per-candidate {us['loop_cpu']:.1f} us CPU/candidate; same design "
          f"(poses {plan.chosen.pose.tolist()})")
    print(f"ratio per-candidate / batched: {us['loop_cpu'] / us['batched_cpu']:.1f}x CPU, "
          f"{us['loop_wall'] / us['batched_wall']:.1f}x wall")
    for n, v in sizes.items():
        print(f"batched make_plan at {n} candidates: {v:.1f} us CPU/candidate")
    load.emit({
        "benchmark": "planner", "baseline_candidates": n0, "repeat": args.repeat,
        "batched_cpu_us_per_candidate": round(us["batched_cpu"], 2),
        "loop_cpu_us_per_candidate": round(us["loop_cpu"], 2),
        "ratio_cpu": round(us["loop_cpu"] / us["batched_cpu"], 2),
        "ratio_wall": round(us["loop_wall"] / us["batched_wall"], 2),
        "batched_cpu_us_per_candidate_at": {str(n): round(v, 2) for n, v in sizes.items()},
        "same_design": True, "load_cases": len(protocol.load_cases),
        "design_tests": protocol.campaign.tests,
        "baseline": ("same algorithm, per candidate, made fast: Pinocchio frame Jacobian and "
                     "frame kinematic Hessian, LAPACK dgesv direct, indices on floats, "
                     "information G o (t t^T); same greedy exchange with the same pose "
                     "separation (make_plan also draws its random reference designs)"),
        "timing": f"CPU time (time.process_time) and wall time, best of {args.repeat} runs "
                  "per side, interleaved, on the same candidates; single-threaded "
                  "(BLAS pinned to 1 thread); the larger sizes batched only",
    })


if __name__ == "__main__":
    main()
