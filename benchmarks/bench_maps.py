"""Benchmark: the 0.5 deg (theta_2, theta_3) map of the KR240-2, batched vs the best per-pose loop.

Work measured: 1/kappa_F, v_p and v_r (which need J, K_C and two deflections)
at every pose.

* Batched: ``pose_metrics`` on the whole 0.5 deg grid, one thread
  (``threads=1`` and BLAS pinned to one thread with threadpoolctl).
* Baseline: the fastest per-pose loop we could write with Pinocchio
  (:class:`PinocchioLoop`): one ``Data`` created once, ``computeJointJacobians``
  + ``computeJointKinematicHessians``, then the Jacobian and the kinematic
  Hessian of the tip frame at P (``getFrameJacobian``,
  ``getFrameKinematicHessian``, LOCAL_WORLD_ALIGNED: K_C exact, no finite
  differences, no shift from the joint origin), LAPACK ``dgesv`` called
  directly for J_N^-1 (kappa_F = ||J_N||_F ||J_N^-1||_F / 6, both norms as dot
  products) and for the deflection, the indices on Python floats. About 2 us
  of it is Pinocchio; the rest is the cost of a dozen small numpy/LAPACK calls
  from Python. Pinocchio is single-threaded; BLAS is pinned to one thread as
  well. Timed on a random sample of the same grid.

Before/after: :func:`previous_kernel` is the kernel ``pose_metrics`` ran before issue 36
(stage functions ``chain_state_em``, ``jacobian_em``, ``inverse_condition_em``,
``complementary_stiffness_em``, ``deflections_em``, ``influence_indices`` on blocks of 4096
poses), kept here and timed in the same runs, interleaved with the current kernel; its
outputs are compared with the current ones (1e-12 relative) before any figure is printed.

All sides are timed the same way, after one untimed run of each: CPU time
(``time.process_time``) and wall time, best of ``--repeat`` runs each, the runs
interleaved (batched, previous, loop, batched, ...) so that load from other processes
hits all alike. Every
output of the loop (1/kappa_F, v_p, v_r) is compared with the batched result at
the same poses before any ratio is printed. The threaded figure (default
thread count, BLAS unpinned) is reported separately, wall time.

The distance from the arithmetic: a pose is about :data:`FLOPS_PER_POSE` floating-point
operations (issue 36's count: forward kinematics, J, the QR of J_N and ||R^-1||_F, K_C,
the LU solve and the indices); the benchmark prints the rate that makes (flop/s) and
how many times the time of a pose at :data:`CORE_GFLOPS` (one core, scalar-ish
vector code) it takes.

Run: ``python benchmarks/bench_maps.py [--sample 3000] [--repeat 3]``
The last line printed is one JSON object with the figures.
"""

from __future__ import annotations

import argparse
import os
import time
from math import sqrt

import numpy as np
import pinocchio as pin
from _load import LoadWindow
from scipy.linalg.lapack import dgesv
from threadpoolctl import threadpool_limits

from analysis.kinetostatics.dexterity import inverse_condition_em
from analysis.kinetostatics.maps import BLOCK, WORST_CASE_WRENCH, GridSpec, pose_metrics
from analysis.kinetostatics.stiffness import (
    complementary_stiffness_em,
    deflections_em,
    influence_indices,
)
from analysis.model.kinematics import chain_state_em, jacobian_em
from analysis.model.robots import load_robot

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
#: floating-point operations per pose of the map kernel, roughly (issue 36)
FLOPS_PER_POSE = 2000
#: a few Gflop/s on one core of the development machine: the ~0.3 us/pose floor of issue 36
CORE_GFLOPS = 6.7


class PinocchioLoop:
    """1/kappa_F, v_p, v_r one pose at a time through Pinocchio (the baseline).

    Made as fast as we can write it in Python: one ``Data`` created once; the
    Jacobian and the kinematic Hessian of the tip frame itself (it sits at P),
    so no shift from the joint origin; LAPACK ``dgesv`` called directly (no
    ``np.linalg`` wrapper, ~4 us less per call), with the matrix handed over in
    the memory order it wants; kappa_F from the trace formula
    ``||J_N||_F ||J_N^-1||_F / 6`` with both norms as dot products; the
    3-vectors of the indices as Python floats.
    """

    def __init__(self, robot, k, w, length):
        self.model, self.data = robot.model, robot.model.createData()
        self.tip = robot.tip_frame
        self.k, self.w = np.asarray(k, dtype=float), np.asarray(w, dtype=float)
        self.inv_k = 1.0 / self.k
        self.scale = np.array([1.0 / length] * 3 + [1.0] * 3)[:, None]
        self.Kt = np.diag(self.k)
        self.eye = np.asfortranarray(np.eye(6))

    def __call__(self, q):
        model, data, tip, w = self.model, self.data, self.tip, self.w
        pin.computeJointJacobians(model, data, q)
        J = pin.getFrameJacobian(model, data, tip, LWA)  # also places the tip frame
        pin.computeJointKinematicHessians(model, data)
        # H[k, i, r] = dJ[r, i]/dq_k at P (LOCAL_WORLD_ALIGNED); K_C[i, k] = (H w)[k, i].
        H = pin.getFrameKinematicHessian(model, data, tip, LWA)
        # K_theta - K_C is the transpose of Kt - H w: a C-ordered matrix's transpose is
        # Fortran-ordered, so LAPACK takes it without a copy.
        A = (self.Kt - H.dot(w)).T
        JN = self.scale * J
        JN_inv, singular = dgesv(JN, self.eye)[2:]
        inv_kappa = 0.0 if singular else 6.0 / sqrt(np.vdot(JN, JN) * np.vdot(JN_inv, JN_inv))
        tau = w.dot(J)
        dk = J.dot(dgesv(A, tau)[2]).tolist()
        dn = J.dot(tau * self.inv_k).tolist()
        a = sqrt(dk[0] * dk[0] + dk[1] * dk[1] + dk[2] * dk[2])
        b = sqrt(dn[0] * dn[0] + dn[1] * dn[1] + dn[2] * dn[2])
        v_r = max(abs(dk[3] - dn[3]), abs(dk[4] - dn[4]), abs(dk[5] - dn[5]))
        return inv_kappa, abs(a - b) / max(a, b), v_r


def previous_kernel(robot, q, k, w, length, block=4096):
    """1/kappa_F, v_p, v_r, deflection of poses q (..., n) as pose_metrics computed them
    before issue 36 (one thread): the stage functions one after the other per block."""
    flat = q.reshape(-1, q.shape[-1])
    scale = np.array([1.0 / length] * 3 + [1.0] * 3)[:, None, None]
    parts = []
    for i in range(0, flat.shape[0], block):
        state = chain_state_em(robot, flat[i:i + block].T)
        E = jacobian_em(state)
        inv_k = inverse_condition_em(E * scale)
        d_kc, d_no = deflections_em(E, k, w, complementary_stiffness_em(E, w))
        v_p, v_r = influence_indices(d_kc.T, d_no.T)
        parts.append({"inv_kappa_F": inv_k, "v_p": v_p, "v_r": v_r, "deflection": d_kc.T})
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def max_rel_diff(a: np.ndarray, b: np.ndarray) -> float:
    """max |a - b| / |a| over the entries where a is not 0 (0 where a == b everywhere)."""
    a, b = np.ravel(a), np.ravel(b)
    nz = a != 0
    if np.any(b[~nz] != 0):
        return float("inf")
    return float(np.max(np.abs(a[nz] - b[nz]) / np.abs(a[nz]), initial=0.0))


def timed(fn):
    """(cpu seconds, wall seconds, result) of one call."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.process_time() - c0, time.perf_counter() - t0, out


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=3000, help="poses for the loop baseline")
    parser.add_argument("--repeat", type=int, default=3, help="runs per side (best is kept)")
    args = parser.parse_args()
    robot = load_robot("kr240-2")
    k, w, L = robot.nominal_stiffness, WORST_CASE_WRENCH, 0.682
    step_deg = 0.5
    q = GridSpec.from_limits(robot, np.radians(step_deg)).poses()
    n = q.shape[0] * q.shape[1]
    flat = q.reshape(-1, 6)
    idx = np.random.default_rng(0).choice(n, size=args.sample, replace=False)
    loop = PinocchioLoop(robot, k, w, L)

    batched_cpu = batched_wall = loop_cpu = loop_wall = prev_cpu = prev_wall = np.inf
    with threadpool_limits(limits=1):
        # one untimed run of each first: imports, the allocator's first pages
        pose_metrics(robot, q, k, w, L, threads=1)
        previous_kernel(robot, q, k, w, L)
        for _ in range(args.repeat):
            c, t, metrics = timed(lambda: pose_metrics(robot, q, k, w, L, threads=1))
            batched_cpu, batched_wall = min(batched_cpu, c), min(batched_wall, t)
            c, t, previous = timed(lambda: previous_kernel(robot, q, k, w, L))
            prev_cpu, prev_wall = min(prev_cpu, c), min(prev_wall, t)
            c, t, ref = timed(lambda: np.array([loop(flat[i]) for i in idx]))
            loop_cpu, loop_wall = min(loop_cpu, c), min(loop_wall, t)
    # issue 36: the current kernel gives the previous kernel's numbers to 1e-12 relative
    unchanged = {key: max_rel_diff(previous[key], metrics[key].reshape(previous[key].shape))
                 for key in previous}
    for key, v in unchanged.items():
        if not v <= 1e-12:
            raise SystemExit(f"{key} moved by {v:.1e} relative from the previous kernel")
    threaded_wall = np.inf
    for _ in range(args.repeat):
        _, t, _ = timed(lambda: pose_metrics(robot, q, k, w, L))
        threaded_wall = min(threaded_wall, t)

    # Same numbers both ways before any ratio (the loop's K_C is exact, so tight).
    errors = {}
    for col, key, rtol, atol in ((0, "inv_kappa_F", 1e-9, 1e-12), (1, "v_p", 1e-7, 1e-12),
                                 (2, "v_r", 1e-7, 1e-15)):
        mine = metrics[key].ravel()[idx]
        np.testing.assert_allclose(mine, ref[:, col], rtol=rtol, atol=atol, err_msg=key)
        errors[key] = float(np.max(np.abs(mine - ref[:, col]) / np.maximum(np.abs(ref[:, col]),
                                                                            atol)))

    us = 1e6
    b_cpu, l_cpu = batched_cpu / n * us, loop_cpu / args.sample * us
    b_wall, l_wall = batched_wall / n * us, loop_wall / args.sample * us
    t_wall = threaded_wall / n * us
    p_cpu, p_wall = prev_cpu / n * us, prev_wall / n * us
    print(f"{step_deg:g} deg map: {q.shape[0]} x {q.shape[1]} = {n} poses; best of {args.repeat}, "
          "interleaved, single-threaded (threads=1, BLAS pinned to 1)")
    print(f"batched numpy:        {b_cpu:7.3f} us CPU/pose, {b_wall:7.3f} us wall/pose "
          f"(blocks of {BLOCK})")
    print(f"previous kernel:      {p_cpu:7.3f} us CPU/pose, {p_wall:7.3f} us wall/pose "
          f"(before issue 36; now {p_cpu / b_cpu:.2f}x faster, CPU); same numbers to "
          + ", ".join(f"{key} {v:.1e}" for key, v in unchanged.items()))
    print(f"Pinocchio loop (frame Hessian K_C, {args.sample} poses): {l_cpu:7.2f} us CPU/pose, "
          f"{l_wall:7.2f} us wall/pose")
    print("outputs agree (max relative difference): "
          + ", ".join(f"{key} {v:.1e}" for key, v in errors.items()))
    print(f"ratio loop / batched: {l_cpu / b_cpu:.1f}x CPU, {l_wall / b_wall:.1f}x wall")
    print(f"threaded batched ({os.cpu_count()} CPUs, BLAS default): {t_wall:.3f} us wall/pose")
    gflops = FLOPS_PER_POSE / (b_cpu * 1e3)
    floor = FLOPS_PER_POSE / (CORE_GFLOPS * 1e3)
    print(f"arithmetic: ~{FLOPS_PER_POSE} flop/pose -> {gflops:.2f} Gflop/s of CPU; "
          f"{b_cpu / floor:.1f}x the {floor:.2f} us/pose of {CORE_GFLOPS:g} Gflop/s "
          f"(the flop count is {b_cpu - floor:.2f} us/pose away)")
    load.emit({
        "benchmark": "maps", "robot": "KR240-2", "grid_step_deg": step_deg, "threads": 1,
        "poses": n, "loop_sample": args.sample, "repeat": args.repeat,
        "batched_cpu_us_per_pose": round(b_cpu, 3), "batched_wall_us_per_pose": round(b_wall, 3),
        "block": BLOCK,
        "previous_kernel_cpu_us_per_pose": round(p_cpu, 3),
        "previous_kernel_wall_us_per_pose": round(p_wall, 3),
        "previous_over_current_cpu": round(p_cpu / b_cpu, 3),
        "max_rel_diff_from_previous_kernel": unchanged,
        "loop_cpu_us_per_pose": round(l_cpu, 3), "loop_wall_us_per_pose": round(l_wall, 3),
        "ratio_cpu": round(l_cpu / b_cpu, 2), "ratio_wall": round(l_wall / b_wall, 2),
        "threaded_wall_us_per_pose": round(t_wall, 3), "cpus": os.cpu_count(),
        "flops_per_pose_estimate": FLOPS_PER_POSE,
        "gflops_per_s_cpu": round(FLOPS_PER_POSE / (b_cpu * 1e3), 3),
        "times_the_flop_floor": round(b_cpu / (FLOPS_PER_POSE / (CORE_GFLOPS * 1e3)), 2),
        "us_per_pose_above_the_flop_floor": round(b_cpu - floor, 3),
        "max_rel_diff": errors,
        "baseline": ("per-pose Pinocchio loop, made fast: Data once, frame Jacobian and frame "
                     "kinematic Hessian at P (LOCAL_WORLD_ALIGNED), LAPACK dgesv called "
                     "directly for J_N^-1 and the deflection, kappa_F by the trace formula, "
                     "the indices on Python floats"),
        "timing": f"CPU time (time.process_time) and wall time, best of {args.repeat} runs "
                  "per side, interleaved (current kernel, previous kernel, loop); threads=1 "
                  "and BLAS pinned to 1 thread on all sides; the loop on a random sample of "
                  "the grid",
    })


if __name__ == "__main__":
    main()
