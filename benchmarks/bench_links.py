"""Benchmark: the cost of a model file with link compliance in ``maps`` and ``compensate``,
per pose, against the same work with the joint springs only (issue 32: <= 1.5x).

Work measured, the same on both sides but for the model file:

* maps: ``pose_metrics`` (1/kappa_F, v_p, v_r, the deflection) on the 1 deg (theta_2,
  theta_3) grid of the KR240-2, one thread (as ``benchmarks/bench_maps.py``'s batched
  row, whose baseline is the Pinocchio per-pose loop);
* compensate: ``compensate_path`` on a wavy 2000-point path with a 1 % compliance
  covariance (as ``benchmarks/bench_compensate.py``'s batched row).

With the axis-2 compensator law (maps and compensate; no covariance of c1, c2): the
KR240-2 with ``compensator = {c1, c2, q2ref_rad}`` in its ``[model_class]`` (c1 = 0.3 x2
per rad, c2 = 0.2 x2 per rad^2, q2ref mid-range): joint 2's stiffness per node
(:mod:`analysis.kinetostatics.compensator_law`);
checked before any ratio: the deflection differs from the joint-only one, equals it
bit for bit at the nodes with q2 = q2ref, and at a sample of nodes equals the joint-only
kernel given that node's k2(q2) (1e-12 relative); the compensated joints move with it.

With links: the KR240-2 with the shop protocol's link compliances of links 2 and 3
(``campaign/protocols/kr240-2-shop.toml`` [fake_lab]) in its ``[model_class]``, and for
compensate the covariance of six of their entries too (their propagation is part of the
work). Before any ratio, the links' outputs are checked: the maps' deflection equals the
joint-only one plus sum_l J_l C_l J_l^T w (1e-12 relative), the compensated joints
differ from the joint-only ones.

Timing: CPU time (``time.process_time``) and wall time, best of ``--repeat`` runs per
side, the sides interleaved (joints, links, joints, ...), BLAS pinned to one thread.
Run: ``python benchmarks/bench_links.py [--repeat 3] [--points 2000]``. Ends with one
JSON line.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
from _load import LoadWindow
from threadpoolctl import threadpool_limits

from analysis.identification.studies.model_classes import shop_lab
from analysis.kinetostatics.compensator_law import pose_stiffness
from analysis.kinetostatics.link_compliance import link_terms, links_of
from analysis.kinetostatics.maps import WORST_CASE_WRENCH, GridSpec, pose_metrics
from analysis.kinetostatics.path_compensation import compensate_path
from analysis.model.robots import load_robot

ENTRIES = ("C2[2,2]", "C2[3,3]", "C2[2,6]", "C3[2,2]", "C3[3,3]", "C3[5,5]")


def timed(fn):
    """(cpu seconds, wall seconds, result) of one call."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.process_time() - c0, time.perf_counter() - t0, out


def with_links(robot):
    """The robot with the shop lab's link compliances and a covariance of ENTRIES (10 %
    standard error each, uncorrelated, no cross term with the joints)."""
    lab = shop_lab()[1]
    links = [{"link": lc.link, "compliance": np.asarray(lc.matrix).tolist()}
             for lc in lab.links]
    value = {lc.link: np.asarray(lc.matrix) for lc in lab.links}
    sd = np.array([0.1 * abs(value[int(n[1])][int(n[3]) - 1, int(n[5]) - 1]) for n in ENTRIES])
    return replace(robot, model_class={
        "version": 2, "name": "links", "links": links,
        "link_covariance": {"parameters": list(ENTRIES), "matrix": np.diag(sd**2).tolist(),
                            "joint_cross": np.zeros((6, len(ENTRIES))).tolist()}})


def with_law(robot):
    """The robot with an axis-2 compensator law in its ``[model_class]`` (q2ref: a node of
    the 1 deg grid near mid-range, so some nodes sit exactly at it)."""
    x2 = 1.0 / robot.nominal_stiffness[1]
    theta2 = GridSpec.from_limits(robot, np.radians(1.0)).theta2
    q2ref = float(theta2[len(theta2) // 2])
    return replace(robot, model_class={
        "version": 2, "name": "compensator",
        "compensator": {"c1": 0.3 * x2, "c2": 0.2 * x2, "q2ref_rad": q2ref}})


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per side (best is kept)")
    parser.add_argument("--points", type=int, default=2000, help="points of the path")
    args = parser.parse_args()
    plain = load_robot("kr240-2")
    linked = with_links(plain)
    lawed = with_law(plain)
    k, w, L = plain.nominal_stiffness, WORST_CASE_WRENCH, 0.682
    grid = GridSpec.from_limits(plain, np.radians(1.0)).poses()
    n_map = grid.shape[0] * grid.shape[1]
    t = np.linspace(0.0, 1.0, args.points)[:, None]
    a = np.radians([0, 30, -200, 40, 50, 30.0])
    b = np.radians([30, 60, -190, 60, 40, -20.0])
    q = a + (b - a) * t + np.radians(2.0) * np.sin(40 * np.pi * t)
    wp = np.array([0, 1000.0, -1500.0, 100.0, 50.0, 0.0])
    cov = np.diag((0.01 / k) ** 2)
    lines = np.arange(args.points) + 2

    best = {key: (np.inf, np.inf) for key in ("maps_joints", "maps_links", "maps_law",
                                              "comp_joints", "comp_links", "comp_law")}
    out = {}

    def keep(name, c, wall, result):
        best[name] = (min(best[name][0], c), min(best[name][1], wall))
        out[name] = result

    with threadpool_limits(limits=1):
        compensate_path(linked, q[:10], k, wp, cov, lines[:10], "path")  # warm-up
        for _ in range(args.repeat):
            for name, robot in (("joints", plain), ("links", linked), ("law", lawed)):
                keep(f"maps_{name}", *timed(lambda r=robot: pose_metrics(r, grid, k, w, L,
                                                                         threads=1)))
            for name, robot in (("joints", plain), ("links", linked), ("law", lawed)):
                keep(f"comp_{name}", *timed(lambda r=robot: compensate_path(
                    r, q, k, wp, cov, lines, "path")))

    # the links are really in the outputs before any ratio
    flat = grid.reshape(-1, 6)
    extra = link_terms(linked, flat, links_of(linked)) @ w
    d_links = out["maps_links"]["deflection"].reshape(-1, 6)
    d_joints = out["maps_joints"]["deflection"].reshape(-1, 6)
    err = float(np.abs(d_links - d_joints - extra).max() / np.abs(d_links).max())
    assert err <= 1e-12, err
    # the law is really in the maps: bit for bit at q2ref, the node's k2(q2) elsewhere
    d_law = out["maps_law"]["deflection"].reshape(-1, 6)
    at_ref = flat[:, 1] == lawed.model_class["compensator"]["q2ref_rad"]
    assert at_ref.any() and np.array_equal(d_law[at_ref], d_joints[at_ref])
    law_moved = float(np.abs(d_law - d_joints).max() / np.abs(d_joints).max())
    assert law_moved > 1e-3, law_moved
    sample = np.random.default_rng(1).choice(len(flat), 50, replace=False)
    k_node = pose_stiffness(lawed, flat[sample], k)
    ref = np.stack([pose_metrics(plain, flat[i], kn, w, L, threads=1)["deflection"]
                    for i, kn in zip(sample, k_node, strict=True)])
    law_err = float(np.abs(ref - d_law[sample]).max() / np.abs(ref).max())
    assert law_err <= 1e-12, law_err
    moved = float(np.abs(out["comp_links"].comp.q_cmd - out["comp_joints"].comp.q_cmd).max())
    law_comp_moved = float(np.abs(out["comp_law"].comp.q_cmd
                                  - out["comp_joints"].comp.q_cmd).max())
    assert law_comp_moved > 1e-6, law_comp_moved
    assert moved > 1e-6, moved
    wider = float(np.max(out["comp_links"].before.sd[:, :3] / out["comp_joints"].before.sd[:, :3]))
    us = 1e6
    row = {}
    for key, count in (("maps", n_map), ("compensate", args.points)):
        short = "comp" if key == "compensate" else "maps"
        (cj, wj), (cl, wl) = best[f"{short}_joints"], best[f"{short}_links"]
        row[key] = {"joints_cpu_us_per_pose": round(cj / count * us, 3),
                    "links_cpu_us_per_pose": round(cl / count * us, 3),
                    "joints_wall_us_per_pose": round(wj / count * us, 3),
                    "links_wall_us_per_pose": round(wl / count * us, 3),
                    "ratio_cpu": round(cl / cj, 3), "ratio_wall": round(wl / wj, 3)}
        if key in ("maps", "compensate"):
            cw, ww = best[f"{short}_law"]
            row[key].update({"law_cpu_us_per_pose": round(cw / count * us, 3),
                             "law_wall_us_per_pose": round(ww / count * us, 3),
                             "law_ratio_cpu": round(cw / cj, 3),
                             "law_ratio_wall": round(ww / wj, 3)})
            print(f"{key} with the compensator law {row[key]['law_cpu_us_per_pose']:.2f} us "
                  f"CPU/pose: {row[key]['law_ratio_cpu']:.2f}x CPU, "
                  f"{row[key]['law_ratio_wall']:.2f}x wall (target <= 1.5x)")
        print(f"{key}: {count} poses; joints {row[key]['joints_cpu_us_per_pose']:.2f} us CPU/pose,"
              f" links {row[key]['links_cpu_us_per_pose']:.2f} us CPU/pose: "
              f"{row[key]['ratio_cpu']:.2f}x CPU, {row[key]['ratio_wall']:.2f}x wall "
              "(target <= 1.5x)")
    print(f"checked: maps deflection = joints + links' to {err:.1e}; compensated joints move "
          f"by up to {moved:.2e} rad with the links; the translation sd grows up to {wider:.2f}x "
          "with the links' covariance")
    load.emit({"benchmark": "links", "robot": "KR240-2", "threads": 1, "repeat": args.repeat,
               "map_grid_step_deg": 1.0, "map_poses": n_map, "path_points": args.points,
               **{f"{key}_{f}": v for key, r in row.items() for f, v in r.items()},
               "target_ratio": 1.5, "max_rel_diff_maps_links": err,
               "max_rel_diff_maps_law_vs_node_k": law_err,
               "baseline": "the same batched work on the joint springs only (the rows of "
                           "bench_maps.py and bench_compensate.py, whose baselines are the "
                           "Pinocchio loops)",
               "timing": f"CPU time (time.process_time) and wall time, best of {args.repeat} "
                         "runs per side, interleaved, BLAS pinned to 1 thread"})


if __name__ == "__main__":
    main()
