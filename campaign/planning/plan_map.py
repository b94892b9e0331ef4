"""The 1/kappa_F map over (theta_2, theta_3) with the planned poses (cf. Fig. 3b of the paper)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel
from campaign.protocol import DEG


def kappa_map(
    robot: RobotModel, q_ref: np.ndarray, length: float, size: int = 181
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """1/kappa_F of J_N on a (theta_2, theta_3) grid over the joint limits (at most one turn).

    Parameters
    ----------
    q_ref : (n,) values of the other joints (rad). length : L (m). size : grid points per axis.

    Returns
    -------
    (t2, t3, inv_kappa) : grid axes (rad) and the map (size, size), indexed [i3, i2].
    """
    lo, hi = robot.map_limits()
    t2 = np.linspace(lo[1], hi[1], size)
    t3 = np.linspace(lo[2], hi[2], size)
    q = np.broadcast_to(np.asarray(q_ref, dtype=float), (size, size, robot.n)).copy()
    q[..., 1] = t2[None, :]
    q[..., 2] = t3[:, None]
    return t2, t3, inverse_condition(normalized_jacobian(jacobian(robot, q), length))


def draw_plan_map(plan, path: Path) -> None:
    """Save the map with zones (boxes), candidates (dots), chosen poses (numbered) to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from analysis.kinetostatics.map_fixed import map_fixed_joints

    robot = plan.robot
    cand = plan.candidates
    chosen = np.unique(plan.chosen.pose)
    # the report's rule: protocol fixed_deg, else the median of the (planned) tested poses
    fixed = map_fixed_joints(robot.n, plan.protocol.sampling.fixed_deg, cand.q[chosen])
    q_ref = fixed.q
    t2, t3, inv_k = kappa_map(robot, q_ref, plan.length)
    fig, ax = plt.subplots(figsize=(7.0, 5.6), dpi=110)
    mesh = ax.contourf(t2 / DEG, t3 / DEG, inv_k, levels=20, cmap="gray")
    fig.colorbar(mesh, ax=ax, label=r"$1/\kappa_F(J_N)$")
    for box in plan.boxes:
        ax.add_patch(Rectangle((box.lo[1] / DEG, box.lo[2] / DEG), (box.hi[1] - box.lo[1]) / DEG,
                               (box.hi[2] - box.lo[2]) / DEG, fill=False, ec="tab:blue", lw=1.2))
        # inside the box's top-left corner: above it, a zone on the upper limit is clipped
        ax.text(box.lo[1] / DEG, box.hi[2] / DEG, box.name, color="tab:blue", fontsize=8,
                va="top", ha="left", bbox={"boxstyle": "round,pad=0.15", "fc": "white",
                                           "ec": "none", "alpha": 0.85}, zorder=4)
    ok = np.any(cand.valid, axis=1)
    ax.plot(cand.q[ok, 1] / DEG, cand.q[ok, 2] / DEG, ".", ms=1, color="tab:cyan", alpha=0.5,
            label=f"candidates passing the thresholds ({int(ok.sum())})")
    rnd = np.unique(plan.random.pose)
    ax.plot(cand.q[rnd, 1] / DEG, cand.q[rnd, 2] / DEG, "s", mfc="none", mec="tab:orange",
            ms=8, label="random zone design")
    ax.plot(cand.q[chosen, 1] / DEG, cand.q[chosen, 2] / DEG, "o", color="tab:red", mec="black",
            ms=7, clip_on=False, zorder=5, label=f"{plan.strategy} design")
    ax.set_title(f"{robot.name}: $1/\\kappa_F$ over ($\\theta_2$, $\\theta_3$) at "
                 f"{fixed.values_text()}\n({fixed.rule_text()})", fontsize=9)
    ax.set_xlabel(r"$\theta_2$ (deg, model convention)")
    ax.set_ylabel(r"$\theta_3$ (deg, model convention)")
    # below the axes: inside, it would hide poses planned near a corner
    legend = ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=3, fontsize=8,
                       frameon=False, markerscale=1.0)
    for handle in legend.legend_handles:  # the candidates' 1-pt dots would not show
        if handle.get_label().startswith("candidates"):
            handle.set_markersize(6)
    fig.tight_layout()
    # poses whose markers overlap at this size: listed under the title (the labels are
    # set apart with leader lines, as on the report's maps)
    from analysis.report.figures import coinciding_on, coinciding_words

    labels = [str(i + 1) for i in range(len(chosen))]
    near = coinciding_words(*coinciding_on(ax, cand.q[chosen, 1] / DEG,
                                           cand.q[chosen, 2] / DEG, labels))
    if near:
        ax.set_title(ax.get_title() + "\n" + near, fontsize=9)
        fig.tight_layout()
    # numbered once the layout is final: each label where it hides no other and no pose
    # (a leader line when moved away), inside the axes (never on the title)
    from analysis.output_files import save_figure
    from analysis.report.figures import place_labels

    place_labels(ax, cand.q[chosen, 1] / DEG, cand.q[chosen, 2] / DEG, labels, 7 / 2 + 1)
    save_figure(fig, path, metadata={"Software": None})
    plt.close(fig)
