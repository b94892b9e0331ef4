"""Benchmark: ``campaign compensate``'s computation on a 10 000-point path, batched vs per point.

Work measured, for every point: the joint-limit and singularity checks
(1/kappa_F of the normalized J), the predicted deflection at the commanded
joints (nonlinear equilibrium ``K_theta dq = J(q + dq)^T w`` by Newton) with
its covariance from that of the compliances, Newton compensation on the
equilibrium (``T(q_c + dq(q_c)) = T(q)``), the limit and residual checks of the
compensated joints and the covariance after compensation.

* Batched: :func:`analysis.kinetostatics.path_compensation.compensate_path` on
  all points at once.
* Baseline: the fastest per-point loop we could write with Pinocchio
  (:class:`PinocchioPoint`): one ``Data`` created once; J and K_C at each
  iterate from the tip frame's Jacobian and kinematic Hessian at P
  (``getFrameJacobian``, ``getFrameKinematicHessian``, LOCAL_WORLD_ALIGNED:
  exact, no finite differences); LAPACK ``dgesv`` called directly for every
  6x6 solve; the SO(3) logarithm by ``pinocchio.log3``; work shared where the
  batched code repeats it: the compensation's first equilibrium (at q, from
  dq = 0) is the predicted deflection, and J and K_C at the compensated
  point's equilibrium, needed for its residual, give the covariance after
  compensation. Run on a sample of points, per-point rate.

Both sides are timed the same way: CPU time (``time.process_time``) and wall
time, best of ``--repeat`` runs each, interleaved, BLAS pinned to one thread
(threadpoolctl) on both sides, after a warm-up. Outputs (q_cmd, the deflection
screw, both covariances, 1/kappa_F) are compared on the sample before any
ratio is printed. Ends with one JSON line.

Run: ``python benchmarks/bench_compensate.py [--points 10000] [--sample 300] [--repeat 3]``
"""

from __future__ import annotations

import argparse
import time
from math import sqrt

import numpy as np
import pinocchio as pin
from _load import LoadWindow
from scipy.linalg.lapack import dgesv
from threadpoolctl import threadpool_limits

from analysis.kinetostatics.compensation import TOLERANCE
from analysis.kinetostatics.path_compensation import MAX_RESIDUAL, MIN_INV_KAPPA, compensate_path
from analysis.model.robots import load_robot

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


class PinocchioPoint:
    """One point of ``compensate_path`` at a time through Pinocchio (the baseline).

    Same checks, tolerances and iteration limits as the batched code: the
    equilibrium's Newton stops at a step <= 1e-14 rad (relative beyond 1 rad),
    at most 50 steps; the compensation's at a pose residual <= TOLERANCE, at
    most 20 steps. A failed check raises ``ValueError``.
    """

    def __init__(self, robot, k, w, cov_x, length):
        self.model, self.data, self.tip = robot.model, robot.model.createData(), robot.tip_frame
        self.lower, self.upper = robot.lower - 1e-12, robot.upper + 1e-12
        self.k = np.asarray(k, dtype=float)
        self.x, self.k2 = 1.0 / self.k, self.k ** 2
        self.Kt = np.diag(self.k)
        self.w = np.asarray(w, dtype=float)
        self.cov_x = np.asarray(cov_x, dtype=float)
        self.scale = np.array([1.0 / length] * 3 + [1.0] * 3)[:, None]
        self.eye = np.asfortranarray(np.eye(6))

    def _jacobian(self, q):
        """J at q and the pose (R, p) of P (copies)."""
        pin.computeJointJacobians(self.model, self.data, q)
        J = pin.getFrameJacobian(self.model, self.data, self.tip, LWA)  # also places P
        oMp = self.data.oMf[self.tip]
        return J, oMp.rotation.copy(), oMp.translation.copy()

    def _hessian_w(self, J):
        """(H w) for the Jacobians just computed: K_C = (H w)^T (a C-ordered H w)."""
        pin.computeJointKinematicHessians(self.model, self.data)
        return pin.getFrameKinematicHessian(self.model, self.data, self.tip, LWA).dot(self.w)

    def _equilibrium(self, q, dq):
        """Joint deflection at q from the guess dq (Newton in compliances, as the batched)."""
        x, w = self.x, self.w
        for _ in range(50):
            J = self._jacobian(q + dq)[0]
            # dF = I - X K_C; its transpose I - (H w) X is C-ordered, LAPACK takes dF.T.T
            dF = (self.eye - self._hessian_w(J) * x).T
            step = dgesv(dF, dq - x * w.dot(J))[2]
            dq = dq - step
            if np.abs(step).max() / max(1.0, np.abs(dq).max()) <= 1e-14:
                return dq
        raise ValueError("equilibrium did not converge")

    def _covariance(self, J, Hw, dq):
        """Covariance of the deflection screw: S cov_x S^T, S = J M^-1 diag(k^2 dq)."""
        S = J.dot(dgesv((self.Kt - Hw).T, np.diag(self.k2 * dq))[2])
        return S.dot(self.cov_x).dot(S.T)

    def __call__(self, q):
        """(q_cmd, before screw, before cov, after cov, 1/kappa_F) at commanded joints q."""
        if np.any(q < self.lower) or np.any(q > self.upper):
            raise ValueError("commanded joints outside the limits")
        J, R0, p0 = self._jacobian(q)
        JN = self.scale * J
        JN_inv, singular = dgesv(JN, self.eye)[2:]
        inv_kappa = 0.0 if singular else 6.0 / sqrt(np.vdot(JN, JN) * np.vdot(JN_inv, JN_inv))
        if inv_kappa < MIN_INV_KAPPA:
            raise ValueError("near a singularity")
        R0t = R0.T
        q_cmd, dq = q.copy(), np.zeros(q.size)
        for it in range(21):
            dq = self._equilibrium(q_cmd, dq)
            J, R, p = self._jacobian(q_cmd + dq)
            Hw = self._hessian_w(J)
            resid = np.concatenate((p - p0, pin.log3(R.dot(R0t))))
            if it == 0:  # at q itself: the predicted deflection and its covariance
                before, cov_before = resid, self._covariance(J, Hw, dq)
            if np.abs(resid).max() <= TOLERANCE:
                break
            if it == 20:
                raise ValueError("compensation did not converge")
            q_cmd = q_cmd - (self.Kt - Hw.T).dot(dgesv(J, resid)[2]) * self.x
        if np.any(q_cmd < self.lower) or np.any(q_cmd > self.upper):
            raise ValueError("compensated joints outside the limits")
        if max(np.abs(resid[:3]).max(), np.abs(resid[3:]).max()) > MAX_RESIDUAL:
            raise ValueError("compensation residual")
        return q_cmd, before, cov_before, self._covariance(J, Hw, dq), inv_kappa


def timed(fn):
    """(cpu seconds, wall seconds, result) of one call."""
    c0, t0 = time.process_time(), time.perf_counter()
    out = fn()
    return time.process_time() - c0, time.perf_counter() - t0, out


def rel_diff(a, b) -> float:
    """Largest |a - b| relative to the largest |b| (one number per output)."""
    a, b = np.asarray(a), np.asarray(b)
    return float(np.abs(a - b).max() / np.abs(b).max())


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=10_000)
    parser.add_argument("--sample", type=int, default=300)
    parser.add_argument("--repeat", type=int, default=3, help="runs per side (best is kept)")
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
    idx = np.linspace(0, args.points - 1, args.sample).astype(int)
    point = PinocchioPoint(robot, k, w, cov, float(robot.characteristic_length))

    best = {"batched": (np.inf, np.inf), "loop": (np.inf, np.inf)}

    def keep(name, c, t):
        best[name] = (min(best[name][0], c), min(best[name][1], t))

    with threadpool_limits(limits=1):
        compensate_path(robot, q[:10], k, w, cov, lines[:10], "path")  # warm-up (imports)
        point(q[0])
        for _ in range(args.repeat):
            c, t, batched = timed(lambda: compensate_path(robot, q, k, w, cov, lines, "path"))
            keep("batched", c, t)
            c, t, loop = timed(lambda: [point(q[i]) for i in idx])
            keep("loop", c, t)

    # same numbers both ways before any ratio
    q_cmd, before, cov_b, cov_a, inv_k = (np.array(v) for v in zip(*loop, strict=True))
    diffs = {"q_cmd_rad_abs": float(np.abs(q_cmd - batched.comp.q_cmd[idx]).max()),
             "screw": rel_diff(before, batched.before.screw[idx]),
             "cov_before": rel_diff(cov_b, batched.before.cov[idx]),
             "cov_after": rel_diff(cov_a, batched.after_cov[idx]),
             "inv_kappa_F": rel_diff(inv_k, batched.inv_kappa[idx])}
    for key, limit in (("q_cmd_rad_abs", 1e-12), ("screw", 1e-9), ("cov_before", 1e-9),
                       ("cov_after", 1e-9), ("inv_kappa_F", 1e-12)):
        assert diffs[key] <= limit, (key, diffs[key])
    res = float(np.abs(batched.comp.residual).max())
    (c_batch, t_batch), (c_loop, t_loop) = best["batched"], best["loop"]
    rate_b, rate_l = args.points / t_batch, args.sample / t_loop
    rate_bc, rate_lc = args.points / c_batch, args.sample / c_loop
    print(f"batched: {args.points} points in {t_batch:.3f} s wall, {c_batch:.3f} s CPU "
          f"({rate_b:.0f} points/s wall); best of {args.repeat}, BLAS pinned to 1 thread")
    print(f"Pinocchio per-point loop: {args.sample} points in {t_loop:.3f} s wall "
          f"({rate_l:.0f} points/s wall, {rate_lc:.0f} CPU)")
    print("outputs agree: " + ", ".join(f"{key} {v:.1e}" for key, v in diffs.items())
          + f"; max residual {res:.2e}")
    print(f"ratio batched / loop: {rate_b / rate_l:.1f}x wall, {rate_bc / rate_lc:.1f}x CPU")
    load.emit({"benchmark": "compensate", "points": args.points, "repeat": args.repeat,
                      "batched_s": round(t_batch, 4), "batched_points_per_s": round(rate_b, 1),
                      "loop_points_per_s": round(rate_l, 1), "ratio": round(rate_b / rate_l, 2),
                      "max_q_cmd_difference_rad": diffs["q_cmd_rad_abs"],
                      "max_deflection_difference": diffs["screw"], "max_rel_diff": diffs,
                      "max_residual": res, "sample": args.sample,
                      "batched_cpu_s": round(c_batch, 4),
                      "loop_cpu_points_per_s": round(rate_lc, 1),
                      "ratio_cpu": round(rate_bc / rate_lc, 2),
                      "baseline": "per-point Pinocchio loop, made fast: Data once, frame "
                                  "Jacobian and frame kinematic Hessian at P, LAPACK dgesv "
                                  "called directly, the predicted deflection shared with the "
                                  "compensation's first equilibrium and the after-covariance "
                                  "with its last; per-point rate on a sample",
                      "timing": "wall time (time.perf_counter) and CPU time "
                                f"(time.process_time), best of {args.repeat} runs per side, "
                                "interleaved, after a warm-up, BLAS pinned to 1 thread on "
                                "both sides"})


if __name__ == "__main__":
    main()
