"""Cartesian compliance and deflection of P with compliant links (virtual-joint model).

THE kernel every command uses for a model with link compliance (``campaign stiffness``
through :func:`deflection_with_links`, ``maps`` through :func:`link_terms`, the
predicted deflection and ``compensate`` through :func:`link_screw`):

    C_X = J (K_theta - K_C)^-1 J^T + sum_l J_l C_l J_l^T,    dX = C_X w,
    K_X = C_X^-1,

J (6, n) the Jacobian of P, K_C the complementary stiffness under w, C_l the 6 x 6
compliance of link l at its distal frame (:func:`analysis.kinetostatics.realistic
.distal_frames`: joint l+1's frame before its rotation) and J_l the twist of P per
virtual motion of that frame (:func:`~analysis.kinetostatics.realistic.virtual_jacobian`).
All SI: C_X rows [m; rad] per [N; N m], K_X its inverse. Batched over poses.
"""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.realistic import LinkCompliance, distal_frames, virtual_jacobian
from analysis.kinetostatics.stiffness import (
    cartesian_compliance,
    complementary_stiffness_from_state,
)
from analysis.model.kinematics import chain_state, jacobian_from_state


def link_terms(robot, q: np.ndarray, links: tuple[LinkCompliance, ...]) -> np.ndarray:
    """sum_l J_l C_l J_l^T (N, 6, 6) at joint angles q (N, n) (rad)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.zeros((q.shape[0], 6, 6))
    if not links:
        return out
    p = chain_state(robot, q).tip[:, :3, 3]
    for lc in links:
        Jl = virtual_jacobian(distal_frames(robot, q, lc.link), p)
        out += Jl @ np.asarray(lc.matrix, dtype=float) @ np.swapaxes(Jl, -1, -2)
    return out


def compliance_with_links(robot, q: np.ndarray, k: np.ndarray, w: np.ndarray,
                          links: tuple[LinkCompliance, ...],
                          with_kc: bool = True) -> np.ndarray:
    """C_X (N, 6, 6) at q (N, n) (rad) under w (6,) or (N, 6) [N; N m] (for K_C), joint
    stiffness k (n,) (N m/rad); ``with_kc`` False drops K_C (eq. 12's compliance)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    state = chain_state(robot, q)
    J = jacobian_from_state(state)
    w = np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6))
    K_C = complementary_stiffness_from_state(state, w) if with_kc else None
    return cartesian_compliance(J, k, K_C) + link_terms(robot, q, links)


def deflection_with_links(robot, q: np.ndarray, k: np.ndarray, w: np.ndarray,
                          links: tuple[LinkCompliance, ...], with_kc: bool = True) -> np.ndarray:
    """dX = C_X w (N, 6) [m; rad] at q (N, n) under w (6,) or (N, 6)."""
    C = compliance_with_links(robot, q, k, w, links, with_kc)
    w = np.broadcast_to(np.asarray(w, dtype=float), (C.shape[0], 6))
    return np.einsum("nij,nj->ni", C, w)


def stiffness_with_links(robot, q, k, w, links, with_kc: bool = True) -> np.ndarray:
    """K_X = C_X^-1 (N, 6, 6)."""
    return np.linalg.inv(compliance_with_links(robot, q, k, w, links, with_kc))


def link_screw(robot, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """sum_l J_l C_l J_l^T w (..., 6) [m; rad] of the links a robot's model file carries
    (:func:`links_of`; zeros without), at q (..., n) under w (..., 6) or (6,)."""
    q = np.asarray(q, dtype=float)
    links = links_of(robot)
    if not links:
        return np.zeros((*q.shape[:-1], 6))
    flat = q.reshape(-1, q.shape[-1])
    wf = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6)).reshape(-1, 6)
    out = np.einsum("nij,nj->ni", link_terms(robot, flat, links), wf)
    return out.reshape((*q.shape[:-1], 6))


def links_of(robot) -> tuple[LinkCompliance, ...]:
    """The link compliances a robot's model file carries (``[model_class]`` of a
    model.toml written by ``campaign analyze --model``), or () (joint springs only)."""
    mc = getattr(robot, "model_class", None) or {}
    return tuple(LinkCompliance(int(e["link"]), np.asarray(e["compliance"], dtype=float))
                 for e in mc.get("links", ()))
