"""Candidate poses: drawn in the zones, evaluated in one batch, filtered by thresholds."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from analysis.errors import InputError
from analysis.kinetostatics.dexterity import inverse_condition_em
from analysis.kinetostatics.maps import BLOCK
from analysis.kinetostatics.small_linalg import to_entry_major
from analysis.kinetostatics.stiffness import (
    complementary_stiffness_em,
    deflections_em,
    influence_indices,
)
from analysis.model.kinematics import chain_state, jacobian_from_state
from analysis.model.robot_model import RobotModel
from campaign.protocol import DEG, Protocol
from campaign.protocol_robot import SamplingBox

#: candidate angles are rounded to this step (deg) so that the plan file holds
#: exactly the angles that were evaluated
ANGLE_STEP_DEG = 1e-3


@dataclass
class Candidates:
    """Evaluated candidate poses (model convention, SI).

    Attributes
    ----------
    q : (N, n) joint angles (rad). zone : (N,) zone index.
    J : (N, 6, n) Jacobians at P. inv_kappa : (N,) 1/kappa_F of J_N.
    v_p : (N, m) eq. 10 per load case (dimensionless). v_r : (N, m) eq. 11 (rad).
    valid : (N, m) test (pose, load case) passes every threshold.
    rejected : counts of rejection reasons.
    """

    q: np.ndarray
    zone: np.ndarray
    J: np.ndarray
    inv_kappa: np.ndarray
    v_p: np.ndarray
    v_r: np.ndarray
    valid: np.ndarray
    rejected: dict[str, int] = field(default_factory=dict)


def _row_scale(length: float) -> np.ndarray:
    """diag(I/L, I) of eq. 4 as an entry-major row scale (6, 1, 1)."""
    return np.array([1.0 / length] * 3 + [1.0] * 3)[:, None, None]


def sample(boxes: list[SamplingBox], count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Draw ``count`` poses spread evenly over the boxes (uniform in each), seeded.

    Returns (q (count, n) rad, zone (count,) int); angles rounded to ANGLE_STEP_DEG.
    """
    rng = np.random.default_rng(seed)
    per = np.full(len(boxes), count // len(boxes))
    per[: count % len(boxes)] += 1
    qs, zs = [], []
    for i, (box, m) in enumerate(zip(boxes, per, strict=True)):
        u = rng.random((int(m), box.lo.size))
        qs.append(box.lo + u * (box.hi - box.lo))
        zs.append(np.full(int(m), i))
    q = np.concatenate(qs)
    step = ANGLE_STEP_DEG * DEG
    q = np.round(q / step) * step
    return q, np.concatenate(zs)


def evaluate(
    protocol: Protocol,
    robot: RobotModel,
    q: np.ndarray,
    zone: np.ndarray,
    k_prior: np.ndarray,
    length: float,
) -> Candidates:
    """Evaluate and filter candidates: limits with margins, 1/kappa_F, v_p and v_r per load case."""
    margin = protocol.safety.joint_margin_deg * DEG
    th = protocol.thresholds
    wrenches = protocol.wrenches()
    inside = robot.within_limits(q, margin - 1e-12)
    N, m = q.shape[0], wrenches.shape[0]
    J = np.empty((N, 6, robot.n))
    inv_kappa = np.empty(N)
    v_p = np.full((N, m), np.nan)
    v_r = np.full((N, m), np.nan)
    # Blocks of poses, BLAS on one thread: large unblocked batches make the 3x3
    # products hit BLAS threading and memory traffic (superlinear time). J is
    # computed once per pose and reused for every load case.
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        for lo in range(0, N, BLOCK):
            sl = slice(lo, min(lo + BLOCK, N))
            J[sl] = jacobian_from_state(chain_state(robot, q[sl]))
            E = to_entry_major(J[sl])
            inv_kappa[sl] = inverse_condition_em(E * _row_scale(length))
            keep = inside[sl] & (inv_kappa[sl] >= th.min_inv_kappa_F)
            if not keep.any():
                continue
            Ek = E[:, :, keep]
            rows = np.flatnonzero(keep) + lo
            for c, w in enumerate(wrenches):
                d_kc, d_no = deflections_em(Ek, k_prior, w, complementary_stiffness_em(Ek, w))
                v_p[rows, c], v_r[rows, c] = influence_indices(d_kc.T, d_no.T)
    dexterous = inside & (inv_kappa >= th.min_inv_kappa_F)
    with np.errstate(invalid="ignore"):
        kc_ok = (v_p <= th.max_v_p) & (v_r <= th.max_v_r_deg * DEG)
    valid = dexterous[:, None] & kc_ok
    if protocol.loads.selection == "all":
        valid = np.repeat(np.all(valid, axis=1, keepdims=True), m, axis=1)
    rejected = {
        "outside limits or margins": int(np.sum(~inside)),
        "1/kappa_F below threshold": int(np.sum(inside & ~dexterous)),
        "K_C not negligible (v_p or v_r)": int(np.sum(dexterous & ~np.any(valid, axis=1))),
    }
    return Candidates(q, zone, J, inv_kappa, v_p, v_r, valid, rejected)


def check_enough(protocol: Protocol, cand: Candidates) -> None:
    """Raise an InputError naming the threshold keys when too few poses pass them."""
    poses = int(np.sum(np.any(cand.valid, axis=1)))
    need = protocol.campaign.tests
    if poses >= need:
        return
    th = protocol.thresholds
    inside = cand.rejected["outside limits or margins"] < cand.q.shape[0]
    best_kappa = float(np.max(cand.inv_kappa)) if cand.q.size else 0.0
    if inside and best_kappa < th.min_inv_kappa_F:
        where = protocol.where("thresholds", "min_inv_kappa_F")
        why = (f"no candidate reaches min_inv_kappa_F = {th.min_inv_kappa_F:g} "
               f"(best found {best_kappa:.4f})")
    else:
        where = protocol.where("thresholds", "max_v_p")
        with np.errstate(invalid="ignore"):
            best_vp = np.nanmin(cand.v_p) if np.any(np.isfinite(cand.v_p)) else np.nan
            best_vr = np.nanmin(cand.v_r) / DEG if np.any(np.isfinite(cand.v_r)) else np.nan
        why = (f"only {poses} poses pass the thresholds, {need} tests are asked for "
               f"(smallest v_p found {best_vp:.4g}, smallest v_r {best_vr:.4g} deg; rejected: "
               + ", ".join(f"{k}: {v}" for k, v in cand.rejected.items()) + ")")
    raise InputError(f"the thresholds leave too few candidates: {why}", where=where)
