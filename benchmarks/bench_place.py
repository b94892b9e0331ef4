"""Speed of the placement search's inner work: (placement, point, tool angle) evaluations.

One evaluation = closed-form IK of the target pose in one configuration, joint
limits, J at P, and the deflection of P under the tool-frame wrench (linear
compliance without K_C). Batched numpy (:func:`analysis.placement.evaluate.evaluate`)
is compared with a per-point loop doing the same work with Pinocchio
(forward kinematics, frame Jacobian) around the same IK called on one pose.
Outputs are compared. Ends with one JSON line.

    python benchmarks/bench_place.py [--placements 16] [--sample 300]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import pinocchio as pin

from analysis.model.ik import IKSolver, fit_limits
from analysis.model.robots import load_robot
from analysis.placement.evaluate import Problem, evaluate
from analysis.placement.poses import target_poses


def per_point(robot, solver, data, T, w_tool, k, margin):
    """The same evaluation for one target pose, Pinocchio for FK and J."""
    q, ok = solver.solve(T[None], (-1, -1, -1), check=False)
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


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--placements", type=int, default=16)
    ap.add_argument("--sample", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    robot = load_robot("kr240-2")
    solver = IKSolver.for_robot(robot)
    n_pts, n_ang = 100, 36
    t = np.linspace(0, 2 * np.pi, n_pts, endpoint=False)
    pts = np.stack([0.15 * np.cos(t), 0.1 * np.sin(t), np.zeros(n_pts)], axis=1)
    w_tool = np.array([400.0, 250.0, -300.0, 0.0, 0.0, 20.0])
    problem = Problem(robot=robot, points=pts, axes=np.tile([0, 0, -1.0], (n_pts, 1)),
                      wrench=np.tile(w_tool, (n_pts, 1)),
                      angles=np.radians(np.arange(0, 360, 10.0)), k=robot.nominal_stiffness,
                      length=0.682, min_inv_kappa=0.05, margin=np.radians(2),
                      max_step=np.radians(10), objective="max", flags=((-1, -1, -1),))
    rng = np.random.default_rng(0)
    G = np.column_stack([rng.uniform(1.3, 2.0, args.placements),
                         rng.uniform(-0.5, 0.5, args.placements),
                         rng.uniform(0.0, 0.6, args.placements),
                         rng.uniform(-0.5, 0.5, args.placements)])
    R = problem.rotations
    best = np.inf
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        tr = evaluate(problem, solver, G, (-1, -1, -1), R)
        best = min(best, time.perf_counter() - t0)
    n = tr.cost.size
    batched_rate = n / best

    T = target_poses(G, pts, R).reshape(-1, 4, 4)
    idx = rng.choice(n, size=args.sample, replace=False)
    data = robot.model.createData()
    t0 = time.perf_counter()
    loop = np.array([per_point(robot, solver, data, T[i], w_tool, robot.nominal_stiffness,
                               problem.margin) for i in idx])
    loop_rate = args.sample / (time.perf_counter() - t0)
    ok = tr.reason.reshape(-1)[idx] == 0
    batched = tr.dp.reshape(-1, 3)[idx]
    agree = np.allclose(loop[ok], batched[ok], rtol=1e-9, atol=1e-15)
    assert agree and np.all(np.isnan(loop[~ok]).all(axis=1))
    print(f"{args.placements} placements x {n_pts} points x {n_ang} angles = {n} evaluations "
          f"in {best:.3f} s: batched numpy {batched_rate:,.0f} evaluations/s "
          f"({ok.mean():.0%} of the sample feasible)")
    print(f"per-point Pinocchio loop: {loop_rate:,.0f} evaluations/s on {args.sample}")
    print(json.dumps({"benchmark": "place", "evaluations": n,
                      "batched_evaluations_per_s": round(batched_rate),
                      "loop_evaluations_per_s": round(loop_rate),
                      "ratio": round(batched_rate / loop_rate, 2),
                      "outputs_agree": bool(agree)}))


if __name__ == "__main__":
    main()
