"""Speed of the placement search's inner work: (placement, point, tool angle) evaluations.

One evaluation = closed-form IK of the target pose in one configuration, joint
limits, J at P, and the deflection of P under the tool-frame wrench (linear
compliance without K_C). Three implementations of the same work, timed the same
way (best of ``--repeat``, wall clock and process CPU time), outputs compared:

* batched: :func:`analysis.placement.evaluate.evaluate`, which for a spherical
  wrist takes J from the IK's frames in structure-of-arrays form;
* general batched: the same IK, then J from the general chain kinematics
  (``evaluate(..., general=True)``, the previous implementation's route);
* per point: the same IK called on one pose, Pinocchio's FK and frame Jacobian.

Two tools: the bare flange (the wrist centre on the tool axis, so the arm is
solved once per point for all tool angles) and a tool offset sideways (arm
solved per angle). Also timed: the whole search step for one configuration
(:func:`analysis.placement.search.evaluate_chunk`: evaluation, continuous angle
selection, verification). The machine's load average is printed: the
development machine is shared, wall-clock figures vary with it. Ends with one
JSON line.

    python benchmarks/bench_place.py [--placements 16] [--sample 300] [--repeat 5]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np
import pinocchio as pin

from analysis.model.ik import IKSolver, fit_limits
from analysis.model.robots import load_robot, with_tool
from analysis.placement.evaluate import OK, Problem, evaluate
from analysis.placement.poses import target_poses
from analysis.placement.search import evaluate_chunk

FLAGS = (-1, -1, -1)


def timed(fn, repeat):
    """(result, best wall time (s), best CPU time (s)) of ``repeat`` calls."""
    wall = cpu = np.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        out = fn()
        wall = min(wall, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    return out, wall, cpu


def per_point(robot, solver, data, T, w_tool, k, margin):
    """The same evaluation for one target pose, Pinocchio for FK and J."""
    q, ok = solver.solve(T[None], FLAGS, check=False)
    q, inside = fit_limits(robot, np.nan_to_num(q), margin)
    if not (ok[0] and inside[0]):
        return np.full(3, np.nan)
    pin.computeJointJacobians(robot.model, data, q[0])
    pin.updateFramePlacements(robot.model, data)
    J = pin.getFrameJacobian(robot.model, data, robot.tip_frame,
                             pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)
    R = T[:3, :3]
    w = np.concatenate([R @ w_tool[:3], R @ w_tool[3:]])
    return J[:3] @ ((J.T @ w) / k)


def case(robot, args, rng, w_tool, loop):
    """Figures of one robot/tool: rates (evaluations/s) and output agreement."""
    solver = IKSolver.for_robot(robot)
    n_pts = 100
    t = np.linspace(0, 2 * np.pi, n_pts, endpoint=False)
    pts = np.stack([0.15 * np.cos(t), 0.1 * np.sin(t), np.zeros(n_pts)], axis=1)
    problem = Problem(robot=robot, points=pts, axes=np.tile([0, 0, -1.0], (n_pts, 1)),
                      wrench=np.tile(w_tool, (n_pts, 1)),
                      angles=np.radians(np.arange(0, 360, 10.0)), k=robot.nominal_stiffness,
                      length=0.682, min_inv_kappa=0.05, margin=np.radians(2),
                      max_step=np.radians(10), objective="max", flags=(FLAGS,))
    G = np.column_stack([rng.uniform(1.3, 2.0, args.placements),
                         rng.uniform(-0.5, 0.5, args.placements),
                         rng.uniform(0.0, 0.6, args.placements),
                         rng.uniform(-0.5, 0.5, args.placements)])
    R = problem.rotations
    evaluate(problem, solver, G[:1], FLAGS, R)  # warm-up
    tr, wall, cpu = timed(lambda: evaluate(problem, solver, G, FLAGS, R), args.repeat)
    n = tr.cost.size
    gen, g_wall, g_cpu = timed(lambda: evaluate(problem, solver, G, FLAGS, R, general=True),
                               max(1, args.repeat // 2))
    ok = tr.reason == OK
    # same reasons; deflections to 1e-12 of the largest (rounding of two evaluation orders)
    general_agree = bool(np.array_equal(tr.reason, gen.reason)
                         and np.allclose(tr.dp[ok], gen.dp[ok], rtol=0,
                                         atol=1e-12 * np.abs(gen.dp[ok]).max(initial=0))
                         and np.allclose(tr.cost[ok], gen.cost[ok], rtol=1e-12, atol=0))
    fig = {"evaluations": n, "feasible": round(float(ok.mean()), 3),
           "batched_per_s": round(n / wall), "batched_cpu_per_s": round(n / cpu),
           "general_batched_per_s": round(n / g_wall),
           "general_batched_cpu_per_s": round(n / g_cpu),
           "general_batched_agrees": general_agree}
    if loop:
        T = target_poses(G, pts, R).reshape(-1, 4, 4)
        idx = rng.choice(n, size=args.sample, replace=False)
        data = robot.model.createData()
        k = robot.nominal_stiffness
        res, l_wall, l_cpu = timed(lambda: np.array([
            per_point(robot, solver, data, T[i], w_tool, k, problem.margin) for i in idx]),
            max(1, args.repeat // 2))
        sok = tr.reason.reshape(-1)[idx] == OK
        agree = bool(np.allclose(res[sok], tr.dp.reshape(-1, 3)[idx][sok], rtol=1e-9, atol=1e-15)
                     and np.all(np.isnan(res[~sok])))
        fig |= {"loop_per_s": round(args.sample / l_wall),
                "loop_cpu_per_s": round(args.sample / l_cpu), "loop_agrees": agree}
        chunk, c_wall, c_cpu = timed(lambda: evaluate_chunk(problem, G), 1)
        fig |= {"search_step_per_s": round(n / c_wall), "search_step_cpu_per_s": round(n / c_cpu),
                "search_feasible_placements": int(np.isfinite(chunk.value).sum())}
    return fig


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--placements", type=int, default=16)
    ap.add_argument("--sample", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    w_tool = np.array([400.0, 250.0, -300.0, 0.0, 0.0, 20.0])
    robot = load_robot("kr240-2")
    load0 = os.getloadavg()[0]
    flange = case(robot, args, np.random.default_rng(0), w_tool, loop=True)
    offset = case(with_tool(robot, np.array([0.06, 0.0, 0.2]), np.zeros(3)), args,
                  np.random.default_rng(0), w_tool, loop=False)
    load = round(max(load0, os.getloadavg()[0]), 1)
    f = flange
    print(f"KR240-2, {f['evaluations']} (placement, point, angle) evaluations, "
          f"{f['feasible']:.0%} feasible; load average {load} on {os.cpu_count()} cores")
    print(f"  batched (J from the IK's frames): {f['batched_per_s']:,} /s wall, "
          f"{f['batched_cpu_per_s']:,} /s CPU")
    print(f"  general batched (chain kinematics for J): {f['general_batched_per_s']:,} /s wall, "
          f"{f['general_batched_cpu_per_s']:,} /s CPU; outputs agree: "
          f"{f['general_batched_agrees']}")
    print(f"  per-point Pinocchio loop: {f['loop_per_s']:,} /s wall, {f['loop_cpu_per_s']:,} /s "
          f"CPU on {args.sample}; outputs agree: {f['loop_agrees']}")
    print(f"  whole search step (evaluation + angle selection + verification): "
          f"{f['search_step_per_s']:,} /s wall, {f['search_step_cpu_per_s']:,} /s CPU")
    print(f"  tool offset 60 mm sideways (arm solved per angle): batched "
          f"{offset['batched_per_s']:,} /s wall, {offset['batched_cpu_per_s']:,} /s CPU; "
          f"general batched agrees: {offset['general_batched_agrees']}")
    agree = f["loop_agrees"] and f["general_batched_agrees"] and offset["general_batched_agrees"]
    print(json.dumps({"benchmark": "place", "evaluations": f["evaluations"],
                      "batched_evaluations_per_s": f["batched_per_s"],
                      "batched_cpu_evaluations_per_s": f["batched_cpu_per_s"],
                      "general_batched_evaluations_per_s": f["general_batched_per_s"],
                      "loop_evaluations_per_s": f["loop_per_s"],
                      "loop_cpu_evaluations_per_s": f["loop_cpu_per_s"],
                      "ratio": round(f["batched_per_s"] / f["loop_per_s"], 1),
                      "ratio_cpu": round(f["batched_cpu_per_s"] / f["loop_cpu_per_s"], 1),
                      "ratio_vs_general_batched": round(
                          f["batched_per_s"] / f["general_batched_per_s"], 1),
                      "search_step_evaluations_per_s": f["search_step_per_s"],
                      "offset_tool_batched_evaluations_per_s": offset["batched_per_s"],
                      "offset_tool_batched_cpu_evaluations_per_s": offset["batched_cpu_per_s"],
                      "load_average": load, "outputs_agree": bool(agree),
                      "sample": args.sample, "placements": args.placements,
                      "baseline": "per-point loop: the same IK on one pose, Pinocchio FK and "
                                  "frame Jacobian",
                      "timing": f"wall time (time.perf_counter) and CPU time "
                                f"(time.process_time), best of {args.repeat} runs (the "
                                f"general batched route and the loop best of "
                                f"{max(1, args.repeat // 2)}), BLAS threads at their "
                                "default; the loop on a random sample"}))
    if not agree:
        raise SystemExit("outputs disagree")


if __name__ == "__main__":
    main()
