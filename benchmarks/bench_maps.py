"""Benchmark: the 0.5 deg (theta_2, theta_3) map of the KR240-2, batched vs a per-pose loop.

Computes 1/kappa_F, v_p and v_r for every node of the 0.5 deg grid with the
batched numpy code, and the same quantities for a sample of poses with a
per-pose loop through Pinocchio (Jacobian, kinematic Hessian for K_C). Prints
both throughputs and their ratio, measured in the same process.

Run: ``python benchmarks/bench_maps.py [--sample 400]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pinocchio as pin

from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.maps import WORST_CASE_WRENCH, GridSpec, pose_metrics
from analysis.model.robots import load_robot


def per_pose_pinocchio(robot, q, k, w, length):
    """1/kappa_F, v_p, v_r at one pose with Pinocchio calls (the loop baseline)."""
    model, data = robot.model, robot.model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.updateFramePlacements(model, data)
    frame = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    J = pin.getFrameJacobian(model, data, robot.tip_frame, frame)
    # K_C by central differences of J^T w through Pinocchio (the loop has no closed form)
    K_C = np.zeros((6, 6))
    h = 1e-7
    for i in range(6):
        e = np.zeros(6)
        e[i] = h
        Jp = pin.computeFrameJacobian(model, data, q + e, robot.tip_frame, frame)
        Jm = pin.computeFrameJacobian(model, data, q - e, robot.tip_frame, frame)
        K_C[:, i] = (Jp.T @ w - Jm.T @ w) / (2 * h)
    inv_k = float(inverse_condition(normalized_jacobian(J, length)))
    d_kc = J @ np.linalg.solve(np.diag(k) - K_C, J.T @ w)
    d_no = J @ ((J.T @ w) / k)
    a, b = np.linalg.norm(d_kc[:3]), np.linalg.norm(d_no[:3])
    return inv_k, abs(a - b) / max(a, b), np.abs(d_kc[3:] - d_no[3:]).max()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sample", type=int, default=400, help="poses for the loop baseline")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    robot = load_robot("kr240-2")
    k, w, L = robot.nominal_stiffness, WORST_CASE_WRENCH, 0.682
    grid = GridSpec.from_limits(robot, np.radians(0.5))
    q = grid.poses()
    n = q.shape[0] * q.shape[1]

    best = np.inf
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        metrics = pose_metrics(robot, q, k, w, L)
        best = min(best, time.perf_counter() - t0)
    batched_rate = n / best

    flat = q.reshape(-1, 6)
    idx = np.random.default_rng(0).choice(n, size=args.sample, replace=False)
    t0 = time.perf_counter()
    loop = np.array([per_pose_pinocchio(robot, flat[i], k, w, L) for i in idx])
    loop_rate = args.sample / (time.perf_counter() - t0)

    # same numbers both ways (K_C by finite differences in the loop: ~1e-6 relative)
    assert np.allclose(loop[:, 0], metrics["inv_kappa_F"].ravel()[idx], rtol=1e-9)
    assert np.allclose(loop[:, 1], metrics["v_p"].ravel()[idx], rtol=1e-3, atol=1e-7)

    print(f"0.5 deg map: {q.shape[0]} x {q.shape[1]} = {n} poses in {best:.3f} s "
          f"(batched numpy: {batched_rate:,.0f} poses/s)")
    print(f"per-pose Pinocchio loop: {loop_rate:,.0f} poses/s on {args.sample} poses")
    print(f"ratio batched / loop: {batched_rate / loop_rate:.1f}x")


if __name__ == "__main__":
    main()
