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
from analysis.model.kinematics import chain_state, chain_state_em, jacobian_from_state


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


def link_displacement_em(robot, q: np.ndarray, links: tuple[LinkCompliance, ...],
                         w: np.ndarray, cos_sin=None, state=None) -> np.ndarray:
    """sum_l J_l C_l J_l^T w (6, N) [m; rad], entry-major: q (n, N) (rad), w (6,) or (6, N)
    [N; N m] at P, base axes; ``cos_sin`` as :func:`~analysis.model.kinematics
    .chain_state_em`'s, or ``state`` a :class:`~analysis.model.kinematics.ChainStateEM`
    made with ``keep`` = :func:`distal_joints` (q then not read). The same quantity as
    :func:`link_terms` times w, without 6 x 6 matrices per pose: with R, o the distal
    frame and r = p - o, J_l^T w = [R^T f; R^T (m + r x f)], y = C_l J_l^T w,
    J_l y = [R y_t + (R y_r) x r; R y_r]."""
    if state is None:
        q = np.asarray(q, dtype=float)
        n = q.shape[0] if cos_sin is None else cos_sin[0].shape[0]
        state = chain_state_em(robot, q, cos_sin, keep=distal_joints(links, n))
    n = state.origins.shape[1]
    p = state.pos
    w = np.asarray(w, dtype=float)
    w = w[:, None] if w.ndim == 1 else w
    f, m = w[:3], w[3:]
    out = np.zeros((6, p.shape[-1]))
    for lc in links:
        R, o = (state.rot, state.pos) if lc.link == n else (state.frames[lc.link],
                                                              state.origins[:, lc.link])
        r = p - o
        mo = m + np.cross(r, f, axis=0)
        v = np.concatenate([(R * f[:, None]).sum(axis=0), (R * mo[:, None]).sum(axis=0)])
        y = np.asarray(lc.matrix, dtype=float) @ v
        yr = (R * y[None, 3:]).sum(axis=1)
        out[:3] += (R * y[None, :3]).sum(axis=1) + np.cross(yr, r, axis=0)
        out[3:] += yr
    return out


def distal_joints(links: tuple[LinkCompliance, ...], n: int) -> tuple[int, ...]:
    """The joints (0-based) whose frames are the links' distal frames (``keep`` of
    :func:`~analysis.model.kinematics.chain_state_em`); the last link's is P's."""
    return tuple(lc.link for lc in links if lc.link < n)


def link_screw(robot, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """sum_l J_l C_l J_l^T w (..., 6) [m; rad] of the links a robot's model file carries
    (:func:`links_of`; zeros without), at q (..., n) under w (..., 6) or (6,)."""
    q = np.asarray(q, dtype=float)
    links = links_of(robot)
    if not links:
        return np.zeros((*q.shape[:-1], 6))
    flat = q.reshape(-1, q.shape[-1])
    wf = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6)).reshape(-1, 6)
    out = link_displacement_em(robot, flat.T, links, wf.T).T
    return out.reshape((*q.shape[:-1], 6))


def links_of(robot) -> tuple[LinkCompliance, ...]:
    """The link compliances a robot's model file carries (``[model_class]`` of a
    model.toml written by ``campaign analyze --model``), or () (joint springs only)."""
    mc = getattr(robot, "model_class", None) or {}
    return tuple(LinkCompliance(int(e["link"]), np.asarray(e["compliance"], dtype=float))
                 for e in mc.get("links", ()))


def link_covariance_of(robot) -> tuple[tuple[str, ...], np.ndarray, np.ndarray] | None:
    """(names ``C2[1,1]``... of the identified link entries, their covariance (L, L), their
    cross-covariance with the joint compliances x = 1/k (n, L)) from a model file's
    ``[model_class.link_covariance]`` (SI), or None (no link compliance, or a file written
    before the links' covariance was kept)."""
    mc = getattr(robot, "model_class", None) or {}
    lc = mc.get("link_covariance")
    if not lc or not lc.get("parameters"):
        return None
    return (tuple(lc["parameters"]), np.asarray(lc["matrix"], dtype=float),
            np.asarray(lc["joint_cross"], dtype=float))


def _entry(name: str) -> tuple[int, int, int]:
    """(link, a, b) (0-based a, b) of an entry name ``C<link>[a,b]`` (1-based a, b)."""
    link = int(name[1:name.index("[")])
    a, b = (int(s) - 1 for s in name[name.index("[") + 1:-1].split(","))
    return link, a, b


def entry_columns(robot, q: np.ndarray, w: np.ndarray, names) -> np.ndarray:
    """G (N, 6, L): the derivative of sum_l J_l C_l J_l^T w [m; rad] with respect to each
    named entry C_l[a, b] (= C_l[b, a], symmetric), at q (N, n) (rad) under w (N, 6) or
    (6,): ``J_l[:, a] (J_l^T w)[b] + J_l[:, b] (J_l^T w)[a]`` (once when a = b); column a
    of J_l is [R e_a; 0] for a translation, [(R e_a) x r; R e_a] for a rotation (R, o
    the distal frame, r = p - o), entry-major inside."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = q.shape[-1]
    w = np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6)).T
    entries = [_entry(name) for name in names]
    st = chain_state_em(robot, q.T, keep=tuple({e[0] for e in entries if e[0] < n}))
    G = np.zeros((6, len(names), q.shape[0]))
    cols: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for i, (link, a, b) in enumerate(entries):
        if link not in cols:
            R, o = (st.rot, st.pos) if link == n else (st.frames[link], st.origins[:, link])
            r = st.pos - o
            Jl = np.zeros((6, 6, r.shape[-1]))
            Jl[:3, :3] = R
            Jl[3:, 3:] = R
            for c in range(3):
                Jl[:3, 3 + c] = np.cross(R[:, c], r, axis=0)
            cols[link] = (Jl, np.einsum("rcN,rN->cN", Jl, w))
        Jl, u = cols[link]
        G[:, i] = Jl[:, a] * u[b]
        if a != b:
            G[:, i] += Jl[:, b] * u[a]
    return np.moveaxis(G, -1, 0)


def link_covariance_terms(robot, q: np.ndarray, w: np.ndarray,
                          S: np.ndarray | None = None) -> np.ndarray:
    """The links' part (..., r, r) of a deflection's covariance, r = 6 or the rows of S:
    ``G Sigma_ll G^T + S Sigma_xl G^T + G Sigma_lx S^T``, G = :func:`entry_columns` at q
    (..., n) under w, S (..., r, n) the deflection's sensitivity to the joint compliances
    (None: no cross term); zeros without a link covariance in the model file. With the
    axis-2 compensator law's covariance, joint 2's cross term is x2(q2)'s
    (:func:`~analysis.kinetostatics.compensator_law.pose_link_cross`)."""
    from analysis.kinetostatics.compensator_law import pose_link_cross

    q = np.asarray(q, dtype=float)
    rows = 6 if S is None else S.shape[-2]
    cov = link_covariance_of(robot)
    if cov is None:
        return np.zeros((*q.shape[:-1], rows, rows))
    names, C_ll, C_xl = cov
    flat = q.reshape(-1, q.shape[-1])
    wf = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6)).reshape(-1, 6)
    G = entry_columns(robot, flat, wf, names)[:, :rows, :].reshape(
        (*q.shape[:-1], rows, len(names)))
    out = G @ C_ll @ np.swapaxes(G, -1, -2)
    if S is not None:
        cross = S @ pose_link_cross(robot, q, C_xl) @ np.swapaxes(G, -1, -2)
        out = out + cross + np.swapaxes(cross, -1, -2)
    return out


def stiffness_diag_se_with_links(robot, q: np.ndarray, k: np.ndarray, w: np.ndarray,
                                 links: tuple[LinkCompliance, ...],
                                 cov_x: np.ndarray) -> np.ndarray:
    """Standard error (N, 6) of diag(K_X), K_X = C_X^-1 with the links (K_C under w), from
    the covariance of the joint compliances x = 1/k (n, n), or per pose (N, n, n) (the
    compensator law's :func:`~analysis.kinetostatics.compensator_law
    .pose_compliance_covariance`), and the model file's link covariance (delta method):
    dK_X = -K_X dC_X K_X with dC_X/dx_j = k_j^2 (J M^-1 e_j) (J M^-T e_j)^T,
    M = K_theta - K_C (not symmetric in general), and dC_X/dC_l[a,b] = J_l (E_ab + E_ba)
    J_l^T."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    k = np.asarray(k, dtype=float)
    n = q.shape[-1]
    w = np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6))
    state = chain_state(robot, q)
    J = jacobian_from_state(state)
    M = k[:, None] * np.eye(n) - complementary_stiffness_from_state(state, w)
    Minv = np.linalg.inv(M)
    V = J @ Minv  # (N, 6, n): J M^-1 e_j in column j
    U = J @ np.swapaxes(Minv, -1, -2)  # J M^-T e_j: K_C is not symmetric in general
    K_X = np.linalg.inv(cartesian_compliance(J, k, complementary_stiffness_from_state(
        state, w)) + link_terms(robot, q, links))
    dC = [k[j] ** 2 * V[:, :, j, None] * U[:, None, :, j] for j in range(n)]
    from analysis.kinetostatics.compensator_law import pose_link_cross

    cov = np.asarray(cov_x, dtype=float)
    lc = link_covariance_of(robot)
    if lc is not None:
        names, C_ll, C_xl = lc
        C_xq = pose_link_cross(robot, q, C_xl)  # C_xl itself without the law's covariance
        p = chain_state(robot, q).tip[:, :3, 3]
        for name in names:
            link, a, b = _entry(name)
            Jl = virtual_jacobian(distal_frames(robot, q, link), p)
            E = np.zeros((6, 6))
            E[a, b] = E[b, a] = 1.0
            dC.append(Jl @ E @ np.swapaxes(Jl, -1, -2))
        if cov.ndim == 2 and C_xq is C_xl:
            cov = np.block([[cov, C_xl], [C_xl.T, C_ll]])
        else:  # per pose: the compensator law's x2(q2) covariance and cross terms
            N = q.shape[0]
            C_xq = np.broadcast_to(C_xq, (N, *C_xl.shape))
            cov = np.concatenate([
                np.concatenate([np.broadcast_to(cov, (N, n, n)), C_xq], axis=-1),
                np.concatenate([np.swapaxes(C_xq, -1, -2),
                                np.broadcast_to(C_ll, (N, *C_ll.shape))], axis=-1)], axis=-2)
    g = np.stack([np.diagonal(-K_X @ d @ K_X, axis1=-2, axis2=-1) for d in dC], axis=-1)
    var = (np.einsum("nap,pr,nar->na", g, cov, g) if cov.ndim == 2 else
           np.einsum("nap,npr,nar->na", g, cov, g))
    return np.sqrt(np.maximum(var, 0.0))
