"""The triple evaluation of :mod:`analysis.placement.evaluate` for a spherical wrist, fast.

Same inputs, outputs and semantics as the general path (IK in one configuration,
joint limits with a margin, keep-out box, deflection of P under the wrench of the
linear compliance model without K_C), computed in structure-of-arrays form:

* the targets are built from quantities of the path computed once in the
  workpiece frame and turned by each placement's yaw (a planar rotation);
* the IK is :func:`analysis.model.ik_soa.solve_wrist`; where the wrist centre does
  not depend on the tool angle (the vector from P to the wrist centre lies on the
  tool axis, the usual spindle), the arm (q1, q2, q3) is solved once per
  (placement, point) and shared by all angles;
* J is not formed: its columns come from the IK's joint axes and origins (the
  wrist axes all pass through the wrist centre, so their lever arm is P minus the
  centre), ``tau = J^T w`` is six dot products, ``dq = tau / k``, ``dp = J_t dq``;
* placements are taken in blocks of about :data:`BLOCK` triples, so the
  temporaries stay in cache.
"""

from __future__ import annotations

import numpy as np

from analysis.model.ik import IKSolver
from analysis.model.ik_soa import apply, cross, dot, rzc, solve_wrist

#: Triples per block: the few dozen temporaries of a block stay in the CPU cache.
BLOCK = 8192
#: Largest change of the wrist centre over the tool angles (m) below which the arm IK
#: is shared by all angles of a point: the effect on P is below the IK's 1e-9 m check.
SHARE_TOL = 1e-12


def _split(a: np.ndarray) -> tuple:
    """(..., 3) array as three contiguous component arrays with a leading unit axis."""
    return tuple(np.ascontiguousarray(a[None, ..., i]) for i in range(3))


def _turn(c, s, v, t=None):
    """Rz(yaw) v (+ t) for yaw cosines/sines c, s of shape (B, 1, 1)."""
    x = c * v[0] - s * v[1]
    y = s * v[0] + c * v[1]
    if t is None:
        return x, y, np.broadcast_to(v[2], np.broadcast_shapes(x.shape, v[2].shape))
    return x + t[0], y + t[1], v[2] + t[2]


class _PathFrame:
    """What a block needs of the path, in the workpiece frame (SoA, (1, N, A or 1))."""

    def __init__(self, problem, solver: IKSolver, R: np.ndarray):
        L = solver.normal
        tool = R @ L.tool  # (N, A, 3): P -> wrist centre
        shared = np.max(np.abs(tool - tool[:, :1]), initial=0.0) <= SHARE_TOL
        if shared:
            tool = tool[:, :1]
        self.centre = _split(problem.points[:, None, :] + tool)
        self.lever = _split(-tool)  # P - wrist centre
        self.z6 = _split(R @ L.k6z)
        self.x6 = _split(R @ L.k6x)
        if problem.wrench is not None:
            w = problem.wrench[:, None, :, None]
            self.force = _split((R @ w[:, :, :3])[..., 0])
            self.moment = _split((R @ w[:, :, 3:])[..., 0])
        self.points = _split(problem.points[:, None, :])


def _fit(q: np.ndarray, lo: float, hi: float):
    """fit_limits for one joint: the whole-turn shift of q nearest the middle of
    [lo, hi] (turns -2..2, ties to the lower), and whether it lies inside."""
    mid = 0.5 * (lo + hi)
    k = q * (-1.0 / (2 * np.pi))
    k += mid / (2 * np.pi) - 0.5
    np.ceil(k, out=k)
    # q is in [-pi, pi]: the clip to -2..2 turns binds only for a middle beyond 1 turn
    if not -2 <= np.ceil(mid / (2 * np.pi) - 1.0) <= np.ceil(mid / (2 * np.pi)) <= 2:
        np.clip(k, -2, 2, out=k)
    k *= 2 * np.pi
    k += q
    ok = (k >= lo) & (k <= hi)
    return np.where(ok, k, q), ok


def _fill(out: np.ndarray, value: np.ndarray, missing: np.ndarray | None, fill) -> None:
    """out[...] = value (broadcast), then ``fill`` where ``missing``."""
    np.copyto(out, value)
    if missing is not None:
        np.copyto(out, fill, where=missing)


def evaluate_wrist(problem, solver: IKSolver, placements: np.ndarray,
                   flags: tuple[int, int, int], R: np.ndarray):
    """(reason, q, cost, dp) for placements (P, 4), as :func:`evaluate` returns them;
    dp is NaN where the IK has no solution."""
    from analysis.placement.evaluate import KEEP_OUT, LIMITS, OK, UNREACHABLE, Z95

    robot = problem.robot
    L = solver.normal
    N, A = R.shape[:2]
    P = placements.shape[0]
    path = _PathFrame(problem, solver, R)
    lo, hi = robot.lower + problem.margin, robot.upper - problem.margin
    fit0 = [_fit(np.zeros(1), lo[j], hi[j])[0][0] for j in range(6)]  # q = 0 where no IK
    inv_k = 1.0 / np.asarray(problem.k, dtype=float)
    reason = np.empty((P, N, A), dtype=np.int8)
    q_out = np.empty((6, P, N, A))
    cost = np.empty((P, N, A))
    dp_out = np.empty((3, P, N, A))
    w5 = L.rot[4][:, 2]  # axis 5 in G_4
    per = max(1, BLOCK // (N * A))
    with np.errstate(invalid="ignore", divide="ignore"):
        for b0 in range(0, P, per):
            pl = placements[b0:b0 + per]
            blk = slice(b0, b0 + per)
            shape = (pl.shape[0], N, A)
            cy = np.cos(pl[:, 3])[:, None, None]
            sy = np.sin(pl[:, 3])[:, None, None]
            t = tuple(pl[:, i][:, None, None] for i in range(3))
            z6 = _turn(cy, sy, path.z6)
            sol = solve_wrist(L, _turn(cy, sy, path.centre, t), z6,
                              _turn(cy, sy, path.x6), flags)
            # joint limits: the arm's joints on the arm's shape (shared by the angles)
            found = np.broadcast_to(sol.ok, shape)
            missing = None if found.all() else ~found
            inside = None
            for j in range(6):
                qj = sol.q[j] if j > 2 else np.where(sol.arm_ok, sol.q[j], 0.0)
                fitted, ok = _fit(qj, lo[j], hi[j])
                _fill(q_out[j, blk], fitted, missing, fit0[j])
                inside = ok if inside is None else inside & ok
            hit = None
            z, o = sol.axes_and_origins(6 if problem.keep_out is not None else 3)
            if problem.keep_out is not None:
                box = problem.keep_out
                hit = np.zeros(shape, dtype=bool)
                for oi in o:
                    hit |= ((oi[0] >= box[0, 0]) & (oi[0] <= box[0, 1]) & (oi[1] >= box[1, 0])
                            & (oi[1] <= box[1, 1]) & (oi[2] >= box[2, 0]) & (oi[2] <= box[2, 1]))
            code = np.where(inside, OK if hit is None else np.where(hit, KEEP_OUT, OK), LIMITS)
            _fill(reason[blk], code, missing, UNREACHABLE)
            # J from the IK's frames: axes 1-3 with their origins (arm shape); axes 4, 5, 6
            # pass through the wrist centre, so their lever arm to P is P - centre
            F = sol.frame4
            z = z[:3] + [F[2], apply(F, rzc(sol.c[3], sol.s[3], w5)), z6]
            p = _turn(cy, sy, path.points, t)
            lever = _turn(cy, sy, path.lever)
            cols = [cross(z[j], tuple(p[i] - o[j][i] for i in range(3))) for j in range(3)]
            d = None
            if problem.wrench is not None:
                f = _turn(cy, sy, path.force)
                m = _turn(cy, sy, path.moment)
                mw = cross(lever, f)  # moment about the wrist centre
                mw = tuple(mw[i] + m[i] for i in range(3))
                tau = [dot(cols[j], f) + dot(z[j], m) for j in range(3)]
                tau += [dot(z[j], mw) for j in range(3, 6)]
                dq = [tau[j] * inv_k[j] for j in range(6)]
                # dp = sum_j dq_j z_j x r_j, the wrist part as (sum dq_j z_j) x lever
                omega = tuple(dq[3] * z[3][i] + dq[4] * z[4][i] + dq[5] * z[5][i]
                              for i in range(3))
                d = cross(omega, lever)
                d = tuple(d[i] + dq[0] * cols[0][i] + dq[1] * cols[1][i] + dq[2] * cols[2][i]
                          for i in range(3))
                for i in range(3):
                    _fill(dp_out[i, blk], d[i], missing, np.nan)
            else:
                dp_out[:, blk] = 0.0
            if problem.objective == "compliance" or problem.cov_x is not None:
                cols += [cross(z[j], lever) for j in range(3, 6)]
            if problem.objective == "compliance":
                C = np.empty((*shape, 3, 3))
                for i in range(3):
                    for i2 in range(i, 3):
                        C[..., i, i2] = C[..., i2, i] = sum(cols[j][i] * cols[j][i2] * inv_k[j]
                                                            for j in range(6))
                value = np.linalg.eigvalsh(np.nan_to_num(C))[..., -1]
            else:
                value = np.sqrt(dot(d, d))
                if problem.cov_x is not None:
                    scale = 1.0 / np.where(value > 0, value, 1.0)
                    u = tuple(d[i] * scale for i in range(3))
                    g = [dot(u, cols[j]) * tau[j] for j in range(6)]
                    var = sum(problem.cov_x[i, j] * g[i] * g[j]
                              for i in range(6) for j in range(6))
                    value = value + Z95 * np.sqrt(np.maximum(var, 0.0))
            np.copyto(cost[blk], value)
            np.copyto(cost[blk], np.inf, where=reason[blk] != OK)
    return reason, np.moveaxis(q_out, 0, -1), cost, np.moveaxis(dp_out, 0, -1)
