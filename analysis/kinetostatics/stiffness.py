"""Cartesian stiffness model (Dumas et al. 2011, eqs. 5-12), pure batched functions.

Sign convention: ``w = [f (N); m (N m)]`` is the external wrench applied on the
end-effector at P, base-frame components. The joints are in equilibrium
``K_theta dtheta = J(theta + dtheta)^T w``; differentiating gives
``(K_theta - K_C) d(dtheta) = J^T dw`` with ``K_C = [dJ^T/dtheta_i w]`` (eq. 8),
hence ``K_X = J^-T (K_theta - K_C) J^-1`` (eq. 6) and the deflection screw
``dX = J (K_theta - K_C)^-1 J^T w``.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import SingularPoseError
from analysis.kinetostatics.small_linalg import solve_dominant, to_entry_major
from analysis.model.kinematics import ChainState, chain_state, jacobian, jacobian_from_state
from analysis.model.robot_model import RobotModel


def complementary_stiffness_from_state(state: ChainState, w: np.ndarray) -> np.ndarray:
    """K_C (..., n, n) (N m/rad) from a kinematic state (see the Jacobian form below)."""
    return complementary_stiffness_from_jacobian(jacobian_from_state(state), w)


def complementary_stiffness_from_jacobian(J: np.ndarray, w: np.ndarray) -> np.ndarray:
    """K_C (..., n, n) (N m/rad), eq. 8: ``K_C[i, k] = d(J^T w)_i / dtheta_k``.

    Closed form for revolute joints, with J_i = [v_i; omega_i] at P in base axes:
    dJ_i/dtheta_k = [omega_k x v_i; omega_k x omega_i] for k <= i, and
    [omega_i x v_k; 0] for k > i. Only J (at P, base axes) is needed.
    """
    J = np.asarray(J, dtype=float)
    w = np.asarray(w, dtype=float)
    if w.ndim > 1:  # one wrench per pose: broadcast, then the same batched kernel
        batch = np.broadcast_shapes(J.shape[:-2], w.shape[:-1])
        J = np.broadcast_to(J, (*batch, *J.shape[-2:]))
        w_em = np.ascontiguousarray(np.broadcast_to(w, (*batch, 6)).reshape(-1, 6).T)
    else:
        batch, w_em = J.shape[:-2], w
    n = J.shape[-1]
    K = complementary_stiffness_em(to_entry_major(J.reshape(-1, 6, n)), w_em)
    return np.moveaxis(K, -1, 0).reshape(*batch, n, n)


def complementary_stiffness_em(E: np.ndarray, w: np.ndarray,
                               out: np.ndarray | None = None) -> np.ndarray:
    """K_C entry-major (n, n, N) from J entry-major (6, n, N) and w (6,) or (6, N).

    The kernel of :func:`complementary_stiffness_from_jacobian`. Triple products
    rewritten as dot products:
    (omega_k x v_i) . f + (omega_k x omega_i) . m = omega_k . (v_i x f + omega_i x m),
    (omega_i x v_k) . f = omega_i . (v_k x f).
    ``out``: an (n, n + k, N) array whose first n columns receive K_C (the others are
    left alone: room for right-hand sides); returned.
    """
    v, om = E[:3], E[3:]  # (3, n, N): components, joint, pose
    w = np.asarray(w, dtype=float)
    f = w[:3].reshape(3, 1, -1) if w.ndim > 1 else w[:3].reshape(3, 1, 1)
    m = w[3:].reshape(f.shape)
    # vf_i = v_i x f and a_i = vf_i + omega_i x m (3, n, N), written in place
    n = E.shape[1]
    vf = np.empty((3, n) + E.shape[2:])
    a = np.empty(vf.shape)
    t = np.empty(vf.shape[1:])
    for c in range(3):
        c1, c2 = (c + 1) % 3, (c + 2) % 3
        np.multiply(v[c1], f[c2], out=vf[c])
        vf[c] -= np.multiply(v[c2], f[c1], out=t)
        np.multiply(om[c1], m[c2], out=a[c])
        a[c] -= np.multiply(om[c2], m[c1], out=t)
        a[c] += vf[c]
    # K[i, k] = a_i . omega_k for k <= i and omega_i . vf_k for k > i: row by row, each
    # entry computed once, written in place (contiguous rows, no (n, n, N) temporaries)
    K = np.empty((n, n) + E.shape[2:]) if out is None else out
    tmp = np.empty((n,) + E.shape[2:])
    for i in range(n):
        _dot_into(K[i, :i + 1], tmp[:i + 1], om[:, :i + 1], a[:, i])
        if i < n - 1:
            _dot_into(K[i, i + 1:n], tmp[i + 1:], vf[:, i + 1:], om[:, i])
    return K


def _dot_into(out: np.ndarray, tmp: np.ndarray, vs: np.ndarray, u: np.ndarray) -> None:
    """out[j] = u . vs[:, j] for vectors vs (3, k, N) and u (3, N), into ``out`` (k, N)."""
    np.multiply(vs[0], u[0], out=out)
    for c in (1, 2):
        np.multiply(vs[c], u[c], out=tmp)
        out += tmp


def complementary_stiffness(robot: RobotModel, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """K_C (..., n, n) at joint angles q (rad) under wrench w (N, N m); see eq. 8."""
    return complementary_stiffness_from_state(chain_state(robot, q), w)


def _kdiag(k: np.ndarray, n: int) -> np.ndarray:
    k = np.asarray(k, dtype=float)
    if k.shape[-1] != n:
        raise ValueError(f"expected {n} joint stiffness values, got {k.shape[-1]}")
    return k[..., :, None] * np.eye(n)


def _check_invertible(J: np.ndarray, what: str) -> None:
    s = np.linalg.svd(J, compute_uv=False)
    bad = s[..., -1] <= s[..., 0] * 1e-12
    if np.any(bad):
        raise SingularPoseError(
            f"{what} needs J^-1 but J is singular at {int(np.sum(bad))} pose(s)", where="q"
        )


def cartesian_stiffness(
    J: np.ndarray, k: np.ndarray, K_C: np.ndarray | None = None
) -> np.ndarray:
    """K_X (..., 6, 6) = J^-T (K_theta - K_C) J^-1 (eq. 6), or eq. 12 when K_C is None.

    Units: translational block N/m, rotational block N m/rad, mixed blocks N/rad, N.
    Raises :class:`SingularPoseError` where J is singular.
    """
    _check_invertible(J, "K_X")
    Kt = _kdiag(k, J.shape[-1])
    if K_C is not None:
        Kt = Kt - K_C
    Jinv = np.linalg.inv(J)
    return np.swapaxes(Jinv, -1, -2) @ Kt @ Jinv


def cartesian_compliance(
    J: np.ndarray, k: np.ndarray, K_C: np.ndarray | None = None
) -> np.ndarray:
    """C = J (K_theta - K_C)^-1 J^T (..., 6, 6); needs no J^-1, defined at singular poses."""
    Kt = _kdiag(k, J.shape[-1])
    if K_C is not None:
        Kt = Kt - K_C
    return J @ np.linalg.solve(Kt, np.swapaxes(J, -1, -2))


def deflection(
    J: np.ndarray, k: np.ndarray, w: np.ndarray, K_C: np.ndarray | None = None
) -> np.ndarray:
    """Deflection screw dX (..., 6) = J (K_theta - K_C)^-1 J^T w: [dp (m); dr (rad)]."""
    tau = np.einsum("...ji,...j->...i", J, np.asarray(w, dtype=float))
    if K_C is None:
        dq = tau / np.asarray(k, dtype=float)  # K_theta is diagonal
    else:
        n = J.shape[-1]
        A = _kdiag(k, n) - K_C
        batch = np.broadcast_shapes(A.shape[:-2], tau.shape[:-1])
        A = np.broadcast_to(A, (*batch, n, n)).reshape(-1, n, n)
        b = np.broadcast_to(tau, (*batch, n)).reshape(-1, n)
        dq = solve_dominant(to_entry_major(A), b.T.copy()).T.reshape(*batch, n)
    return np.einsum("...ij,...j->...i", J, dq)


def deflections_em(
    E: np.ndarray, k: np.ndarray, w: np.ndarray, K_C: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Deflections (6, N) with and without K_C, entry-major J (6, n, N) and K_C (n, n, N).

    The kernel of :func:`deflection` for maps: K_theta - K_C is diagonally
    dominant for industrial robots under realistic wrenches, so it is solved by
    batched elimination without pivoting (LAPACK where the guard fails).
    """
    k = np.asarray(k, dtype=float)
    n = E.shape[1]
    tau = np.einsum("rin,r->in", E, np.asarray(w, dtype=float))  # J^T w, (n, N)
    A = -K_C
    A[np.arange(n), np.arange(n)] += k[:, None]
    dq = solve_dominant(A, tau, overwrite_a=True)  # A is this function's own scratch
    d_kc = np.einsum("rin,in->rn", E, dq)
    d_no = np.einsum("rin,in->rn", E, tau / k[:, None])
    return d_kc, d_no


def influence_indices(d_kc: np.ndarray, d_no: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """v_p (eq. 10) and v_r (eq. 11, rad) from the deflections with and without K_C (..., 6).

    v_p = |dp_KC - dp_noKC| / max(dp_KC, dp_noKC) with dp the norm of the
    translational deflection (0 where both are 0); v_r = max_i |dr_KC,i - dr_noKC,i|.
    """
    n_kc = np.linalg.norm(d_kc[..., :3], axis=-1)
    n_no = np.linalg.norm(d_no[..., :3], axis=-1)
    denom = np.maximum(n_kc, n_no)
    v_p = np.where(denom > 0, np.abs(n_kc - n_no) / np.where(denom > 0, denom, 1.0), 0.0)
    v_r = np.max(np.abs(d_kc[..., 3:] - d_no[..., 3:]), axis=-1)
    return v_p, v_r


def kc_influence(
    robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Indices v_p (eq. 10, dimensionless) and v_r (eq. 11, rad) of the influence of K_C
    at joint angles q (..., n) (rad) under wrench w (N, N m), joint stiffness k (N m/rad)."""
    J = jacobian(robot, q)
    K_C = complementary_stiffness_from_jacobian(J, w)
    return influence_indices(deflection(J, k, w, K_C), deflection(J, k, w))
