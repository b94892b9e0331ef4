"""The map kernel: 1/kappa_F, the deflections with and without K_C, v_p and v_r of a block
of poses in one pass, entry-major (the pose index last and contiguous).

The same formulas as the stage functions it replaces in :func:`~analysis.kinetostatics
.maps.pose_metrics` (``chain_state_em``, ``jacobian_em``, ``inverse_condition_em``,
``complementary_stiffness_em``, ``deflections_em``, ``influence_indices``), computed with
fewer passes over the block:

* cos and sin of a joint are computed once per distinct value along the axes of the
  input grid over which the joint does not vary (:func:`grid_cos_sin`), and a joint at
  one angle in a whole block is a float, so the frames before the first varying joint
  cost nothing per pose;
* ||J_N^-1||_F by the modified Gram-Schmidt QR of ``inverse_frobenius2``, each step
  over all the columns still to be orthogonalised at once, the scale 1/L of the
  translational rows applied while copying J;
* K_theta - K_C solved as the augmented system [K_C - K_theta | J^T w] eliminated in
  place (the forward substitution done with the elimination), with no diagonal-dominance
  pass over the block when a bound from the chain's link lengths and |w| proves every
  pose of the robot dominant (:func:`dominance_proved`).

Where ``inverse_frobenius2`` and ``deflections_em`` reduce with ``einsum``, this kernel
sums the same products in order with ``np.add.reduce``: the results agree to rounding
(1e-12 relative is tested).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.kinetostatics.small_linalg import diagonally_dominant, lu_em, solve_dominant
from analysis.kinetostatics.stiffness import complementary_stiffness_em
from analysis.model.kinematics import ChainStateEM, chain_state_em, jacobian_em


@dataclass(frozen=True)
class GridCosSin:
    """cos and sin of each joint over a flat batch of poses, for slicing into blocks.

    ``cos[j]``/``sin[j]``: a float (joint j at one angle in every pose), an (N,) array
    (joint j varies along some but not all axes of the input grid: computed once per
    distinct value, then spread), or None (computed per block from q).
    """

    cos: tuple
    sin: tuple

    def block(self, q: np.ndarray, start: int) -> tuple[list, list]:
        """(cos, sin) lists of the block q (B, n) starting at flat pose ``start``; a
        joint at one angle throughout the block is a float."""
        stop = start + q.shape[0]
        cos, sin = [], []
        for j, (c, s) in enumerate(zip(self.cos, self.sin, strict=True)):
            if isinstance(c, np.ndarray):
                c, s = c[start:stop], s[start:stop]
            elif c is None:
                col = q[:, j]
                if col.size and np.all(col == col[0]):  # one angle: 2 calls, not B
                    a = col[0]
                    c, s = float(np.cos(a)), float(np.sin(a))
                else:
                    c, s = np.cos(col), np.sin(col)
            cos.append(c)
            sin.append(s)
        return cos, sin


def grid_cos_sin(q: np.ndarray) -> GridCosSin:
    """:class:`GridCosSin` of poses q (..., n) (rad), grid axes first.

    A joint constant along some of the grid's axes (a map's theta_2 along theta_3's
    axis) has its cos and sin computed on the grid reduced along them, then spread to
    the flat batch: the same values, np.cos and np.sin called on fewer angles.
    """
    shape = q.shape[:-1]
    if not np.prod(shape):
        return GridCosSin((None,) * q.shape[-1], (None,) * q.shape[-1])
    cos, sin = [], []
    for j in range(q.shape[-1]):
        v = q[..., j]
        for axis in range(len(shape)):
            if v.shape[axis] > 1:
                first = v.take([0], axis=axis)
                if np.all(v == first):
                    v = first
        if v.size == 1:
            a = v.reshape(())
            cos.append(float(np.cos(a)))
            sin.append(float(np.sin(a)))
        elif v.size < np.prod(shape):
            cos.append(np.broadcast_to(np.cos(v), shape).reshape(-1))
            sin.append(np.broadcast_to(np.sin(v), shape).reshape(-1))
        else:
            cos.append(None)
            sin.append(None)
    return GridCosSin(tuple(cos), tuple(sin))


def dominance_proved(robot, k: np.ndarray, w: np.ndarray) -> bool:
    """True when K_theta - K_C is strictly row diagonally dominant at every pose of
    ``robot`` under the wrench w (6,) (N, N m), joint stiffness k (n,) (N m/rad).

    With v_i the translational column of J (|v_i| <= rho_i, the chain's length from
    joint i's origin to P) and unit axes omega: |K_C[i, l]| <= |a_i| <= rho_i |f| + |m|
    for l <= i and <= rho_l |f| for l > i (:func:`~analysis.kinetostatics.stiffness
    .complementary_stiffness_em`'s dot products). A bound, not a test: when it fails the
    block is tested pose by pose as before.
    """
    w = np.asarray(w, dtype=float)
    if w.ndim != 1:
        return False
    nc = robot.chain.normal
    n = nc.pos.shape[0]
    links = np.linalg.norm(nc.pos, axis=1)
    tip = float(np.linalg.norm(nc.tip_pos))
    # rho_i: |p - o_i| <= sum of the placements after joint i and the tip's offset
    rho = np.array([links[i + 1:].sum() + tip for i in range(n)])
    f, m = float(np.linalg.norm(w[:3])), float(np.linalg.norm(w[3:]))
    margin = 1.0 + 1e-6  # rounding of the unit axes and of the sums, generously
    for i in range(n):
        row = (i + 1) * (rho[i] * f + m) + f * rho[i + 1:].sum()
        if not k[i] > row * margin:
            return False
    return True


def block_metrics(robot, q: np.ndarray, cos: list, sin: list, k: np.ndarray,
                  w: np.ndarray, length: float, dominant: bool,
                  keep: tuple[int, ...] = ()) -> tuple[ChainStateEM, dict]:
    """The map's figures of one block of poses q (B, n) (rad), entry-major inside.

    ``cos``, ``sin``: per joint, a float or a (B,) array (:meth:`GridCosSin.block`);
    k: (n,) or, per pose (a model file's compensator law), (n, B) (N m/rad);
    ``dominant``: :func:`dominance_proved` for (robot, k, w); ``keep``: frames to keep
    for link compliance. Returns the chain state and
    {inv_kappa_F (B,), d_kc (6, B), d_no (6, B)}: 1/kappa_F of J_N (0 where singular),
    the deflection screws [m; rad] under w with and without K_C.
    """
    B = q.shape[0]
    state = chain_state_em(robot, np.empty((0, B)), (cos, sin), keep=keep)
    E = jacobian_em(state)  # J (6, n, B)
    inv_k = inverse_condition(E, length)
    d_kc, d_no = deflections(E, k, w, dominant)
    return state, {"inv_kappa_F": inv_k, "d_kc": d_kc, "d_no": d_no}


def inverse_condition(E: np.ndarray, length: float) -> np.ndarray:
    """1/kappa_F (B,) of J_N = diag(I/L, I) J for J entry-major (6, n, B); 0 where singular.

    kappa_F = ||J_N||_F ||J_N^-1||_F / n with ||J_N^-1||_F = ||R^-1||_F from the modified
    Gram-Schmidt QR of J_N (as ``inverse_frobenius2``); exactly singular matrices go to
    the singular values (as ``frobenius_condition_em``).
    """
    rows, n, B = E.shape
    # columns of J_N, each a contiguous (6, B) slab: C[j] = J_N[:, j]
    C = np.empty((n, rows, B))
    Et = E.transpose(1, 0, 2)
    np.multiply(Et[:, :3], 1.0 / length, out=C[:, :3])
    C[:, 3:] = Et[:, 3:]
    T = np.empty((n, rows, B))
    np.multiply(C, C, out=T)
    fro2 = np.add.reduce(T.reshape(n * rows, B), axis=0)  # ||J_N||_F^2
    R = np.empty((n, n, B))  # only the upper triangle is written and read
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for j in range(n):
            a = C[j]
            r = R[j, j]
            np.multiply(a, a, out=T[0])
            np.add.reduce(T[0], axis=0, out=r)
            np.sqrt(r, out=r)
            np.divide(a, r, out=a)
            if j < n - 1:
                # every later column loses its component along q_j, all at once
                rest, t = C[j + 1:], T[:n - j - 1]
                np.multiply(rest, a, out=t)
                rj = R[j, j + 1:]
                np.add.reduce(t, axis=1, out=rj)
                np.multiply(a, rj[:, None, :], out=t)
                rest -= t
        # ||R^-1||_F^2 column by column from the bottom, as inverse_frobenius2
        inv = 1.0 / R[np.arange(n), np.arange(n)]  # (n, B)
        total = np.zeros(B)
        x = np.empty((n, B))
        t = T[0]
        for m in range(n):
            x[m] = inv[m]
            for i in range(m - 1, -1, -1):
                s = t[:m - i]
                np.multiply(R[i, i + 1:m + 1], x[i + 1:m + 1], out=s)
                np.add.reduce(s, axis=0, out=x[i])
                x[i] *= -inv[i]
            sq = t[:m + 1]
            np.multiply(x[:m + 1], x[:m + 1], out=sq)
            total += np.add.reduce(sq, axis=0)
    bad = ~np.isfinite(total)
    if np.any(bad):
        # some matrix is exactly singular: its singular values, as frobenius_condition_em
        M = np.concatenate([E[:3, :, bad] / length, E[3:, :, bad]])
        s = np.linalg.svd(np.moveaxis(M, -1, 0), compute_uv=False)
        singular = s[..., -1] <= s[..., 0] * 1e-15
        safe = np.where(singular[..., None], 1.0, s)
        total[bad] = np.where(singular, np.inf, np.sum(1.0 / safe**2, axis=-1))
    with np.errstate(over="ignore", invalid="ignore"):
        kappa = np.sqrt(fro2 * total) / n
    return np.where(kappa > 1e15, 0.0, 1.0 / kappa)


def deflections(E: np.ndarray, k: np.ndarray, w: np.ndarray,
                dominant: bool) -> tuple[np.ndarray, np.ndarray]:
    """Deflection screws (6, B) with and without K_C under w (6,), J entry-major (6, n, B),
    joint stiffness k (n,) or per pose (n, B) (N m/rad).

    dq = (K_theta - K_C)^-1 J^T w as the augmented system [K_C - K_theta | J^T w] (its
    solution is -dq; negation is exact, so the numbers are those of eliminating
    K_theta - K_C), without pivoting where every pose is diagonally dominant (proved
    by ``dominant`` or tested pose by pose), by ``numpy.linalg.solve`` otherwise.
    """
    k = np.asarray(k, dtype=float)
    kb = k[:, None] if k.ndim == 1 else k  # (n, 1) or per pose (n, B)
    w = np.asarray(w, dtype=float)
    rows, n, B = E.shape
    aug = np.empty((n, n + 1, B))
    complementary_stiffness_em(E, w, out=aug)
    diag = aug[np.arange(n), np.arange(n)]  # a copy (fancy index), written back below
    diag -= kb
    aug[np.arange(n), np.arange(n)] = diag
    T = np.empty((rows, n, B))
    np.multiply(E, w[:, None, None], out=T)
    tau = aug[:, n]
    np.add.reduce(T, axis=0, out=tau)  # J^T w (n, B)
    tau_k = tau / kb  # the joint deflections without K_C, before tau is eliminated
    ok = None if dominant else diagonally_dominant(aug[:, :n])
    if ok is not None and not ok.all():
        A = -aug[:, :n]  # K_theta - K_C, exactly
        dq = solve_dominant(A, tau.copy(), dominant=ok, overwrite_a=True)
    else:
        lu_em(aug)  # the last column becomes L^-1 J^T w: only the back substitution is left
        x = aug[:, n]
        tmp = np.empty(B)
        for i in range(n - 1, -1, -1):  # as lu_solve_em's second half
            s = x[i]
            for m in range(i + 1, n):
                np.multiply(x[m], aug[i, m], out=tmp)
                s -= tmp
            s /= aug[i, i]
        dq = np.negative(x)
    d = np.empty((2, rows, B))
    np.multiply(E, dq, out=T)
    np.add.reduce(T, axis=1, out=d[0])
    np.multiply(E, tau_k, out=T)
    np.add.reduce(T, axis=1, out=d[1])
    return d[0], d[1]


def influence(d_kc: np.ndarray, d_no: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """v_p and v_r (rad) (B,) from the deflection screws (6, B), as ``influence_indices``."""
    sq = d_kc[:3] * d_kc[:3]
    n_kc = np.sqrt(np.add.reduce(sq, axis=0))
    np.multiply(d_no[:3], d_no[:3], out=sq)
    n_no = np.sqrt(np.add.reduce(sq, axis=0))
    denom = np.maximum(n_kc, n_no)
    with np.errstate(divide="ignore", invalid="ignore"):
        v_p = np.abs(n_kc - n_no) / denom
    v_p[~(denom > 0)] = 0.0
    diff = d_kc[3:] - d_no[3:]
    np.abs(diff, out=diff)
    return v_p, np.max(diff, axis=0)
