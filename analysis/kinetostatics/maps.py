"""Maps of dexterity and of the influence of K_C (Dumas et al. 2011, Figs. 3 and 5).

A map is a tidy table with one row per grid pose: the (theta_2, theta_3) grid
with the other joints fixed (paper defaults: theta_1 = 0, theta_4..6 = 45 deg),
the Cartesian position of P for the same poses (the workspace view), and
1/kappa_F, v_p and v_r. Everything is computed in one batched pass.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from analysis.kinetostatics.map_kernel import (
    block_metrics,
    dominance_proved,
    grid_cos_sin,
    influence,
)
from analysis.model.robot_model import RobotModel

if TYPE_CHECKING:  # pandas is imported where a table is built (CLI start-up time)
    import pandas as pd

#: Worst-case wrench of the paper's section 3 (N, N m): 2200 N along and 400 N m about each axis.
WORST_CASE_WRENCH = np.array([2200.0, 2200.0, 2200.0, 400.0, 400.0, 400.0])
#: Wrench of the robustness study, eq. 22 (N, N m).
W_EFF = np.array([0.0, 2200.0, 2200.0, 200.0, 200.0, 0.0])
#: Rank-deficiency threshold on 1/kappa_F below which a pose is reported singular.
SINGULAR_INV_KAPPA = 1e-9


@dataclass(frozen=True)
class GridSpec:
    """A (theta_2, theta_3) grid in the model convention (rad)."""

    theta2: np.ndarray
    theta3: np.ndarray
    fixed: np.ndarray  # (n,) values of the other joints (rad); entries 1 and 2 are ignored

    @classmethod
    def from_limits(
        cls, robot: RobotModel, step: float, fixed: np.ndarray | None = None
    ) -> GridSpec:
        """Grid over the joint limits of joints 2 and 3 with ``step`` (rad), at most one turn."""
        if fixed is None:
            fixed = np.zeros(robot.n)
            fixed[3:] = np.radians(45.0)
        lo, hi = robot.map_limits()
        t2 = np.arange(lo[1], hi[1] + step / 2, step)
        t3 = np.arange(lo[2], hi[2] + step / 2, step)
        return cls(t2, t3, np.asarray(fixed, dtype=float))

    def poses(self) -> np.ndarray:
        """Joint angles (n2, n3, n) of every grid node (rad)."""
        T2, T3 = np.meshgrid(self.theta2, self.theta3, indexing="ij")
        q = np.broadcast_to(self.fixed, (*T2.shape, self.fixed.size)).copy()
        q[..., 1], q[..., 2] = T2, T3
        return q


#: Poses per block. Measured on the 0.5 deg KR240-2 map, one thread (us CPU/pose, best of
#: 6 interleaved runs, load 5.6-6.6 on 2 cores): 1024: 1.17, 2048: 0.87, 4096: 0.86-0.99,
#: 8192: 0.74-0.86, 16384: 0.77-0.89, 32768: 1.12. Below 4096 the ~500 numpy calls of a
#: block cost more per pose; above 16384 a block's arrays no longer stay in the caches.
BLOCK = 8192


def pose_metrics(
    robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray, length: float,
    threads: int | None = None,
) -> dict[str, np.ndarray]:
    """1/kappa_F, v_p, v_r (rad), the deflections and P's position for poses q (..., n).

    ``singular`` is True where J is rank deficient: 1/kappa_F is then 0; v_p and
    v_r stay defined (they need no J^-1) but a caller must show the flag.
    Large batches are cut into blocks computed on ``threads`` threads (default:
    the CPU count); NumPy releases the GIL inside its kernels. k (n,) is the file's
    stiffness (N m/rad); a model file with the axis-2 compensator law has k2(q2) per
    pose (:func:`~analysis.kinetostatics.compensator_law.pose_stiffness`).
    """
    from analysis.kinetostatics.compensator_law import compensator_law_of, pose_stiffness
    from analysis.kinetostatics.link_compliance import distal_joints, links_of

    q = np.asarray(q, dtype=float)
    k = np.asarray(k, dtype=float)
    w = np.asarray(w, dtype=float)
    shape = q.shape[:-1]
    flat = q.reshape(-1, q.shape[-1])
    trig = grid_cos_sin(q)  # a map's fixed joints and grid axes: fewer cos and sin
    links = links_of(robot)  # a model file's link compliance: its distal frames kept
    # the compensator law: joint stiffness per pose, entry-major (n, N); None: k for all
    k_em = (np.ascontiguousarray(pose_stiffness(robot, flat, k).T)
            if compensator_law_of(robot) is not None else None)
    # dominance from the smallest stiffness of each joint over the poses (a bound for all)
    k_dom = k if k_em is None else (k_em.min(axis=1) if k_em.size else k)
    setup = (trig, dominance_proved(robot, k_dom, w), links,
             distal_joints(links, flat.shape[-1]), k_em)
    starts = range(0, max(flat.shape[0], 1), BLOCK)
    blocks = [(i, flat[i:i + BLOCK]) for i in starts]
    workers = min(len(blocks), threads or os.cpu_count() or 1)
    if workers <= 1:
        parts = [_pose_metrics(robot, b, i, k, w, length, setup) for i, b in blocks]
    else:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=workers) as pool:
            parts = list(pool.map(
                lambda ib: _pose_metrics(robot, ib[1], ib[0], k, w, length, setup), blocks))
    return {
        key: np.concatenate([p[key] for p in parts]).reshape((*shape, *parts[0][key].shape[1:]))
        for key in parts[0]
    }


def _pose_metrics(robot, q, start, k, w, length, setup):
    """The kernel of :func:`pose_metrics` on one block of poses q (N, n) starting at flat
    pose ``start`` (:func:`~analysis.kinetostatics.map_kernel.block_metrics`)."""
    trig, dominant, links, keep, k_em = setup
    cos, sin = trig.block(q, start)
    if k_em is not None:  # the compensator law: this block's k (n, B)
        k = k_em[:, start:start + q.shape[0]]
    state, m = block_metrics(robot, q, cos, sin, k, w, length, dominant, keep)
    d_kc, d_no = m["d_kc"], m["d_no"]
    if links:  # a model.toml with link compliance: + sum_l J_l C_l J_l^T w (the one kernel)
        from analysis.kinetostatics.link_compliance import link_displacement_em

        extra = link_displacement_em(robot, None, links, w, state=state)
        d_kc, d_no = d_kc + extra, d_no + extra
    v_p, v_r = influence(d_kc, d_no)
    inv_k = m["inv_kappa_F"]
    return {
        "inv_kappa_F": inv_k,
        "v_p": v_p,
        "v_r": v_r,
        "singular": inv_k < SINGULAR_INV_KAPPA,
        "position": state.pos.T,
        "deflection": d_kc.T,
    }


def joint_space_map(
    robot: RobotModel, grid: GridSpec, k: np.ndarray, w: np.ndarray, length: float
) -> pd.DataFrame:
    """Tidy table of the map: one row per (theta_2, theta_3) node.

    Columns: ``theta2_deg, theta3_deg`` (model convention), ``x_m, y_m, z_m``
    (position of P), ``inv_kappa_F``, ``v_p``, ``v_r_deg``, ``deflection_mm``
    (norm of the translational deflection under w, with K_C), ``singular``.
    """
    import pandas as pd

    q = grid.poses()
    m = pose_metrics(robot, q, k, w, length)
    pos = m["position"].reshape(-1, 3)
    return pd.DataFrame(
        {
            "theta2_deg": np.degrees(q[..., 1]).ravel(),
            "theta3_deg": np.degrees(q[..., 2]).ravel(),
            "x_m": pos[:, 0],
            "y_m": pos[:, 1],
            "z_m": pos[:, 2],
            "inv_kappa_F": m["inv_kappa_F"].ravel(),
            "v_p": m["v_p"].ravel(),
            "v_r_deg": np.degrees(m["v_r"]).ravel(),
            "deflection_mm": 1e3 * np.linalg.norm(m["deflection"][..., :3], axis=-1).ravel(),
            "singular": m["singular"].ravel(),
        }
    )
