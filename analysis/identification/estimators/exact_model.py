"""The exact (nonlinear) model of a stiffness test, written in joint compliances.

For joint compliances x (rad/(N m)), the joint deflection solves
``dq = x * J(q + dq)^T w`` (the equilibrium ``K_theta dq = J(q+dq)^T w`` with
K_theta = diag(1/x)); the measured displacement is the finite screw
``[p(q+dq) - p(q); rotvec(R(q+dq) R(q)^T)]``. Written in x, the model stays
defined for rigid joints (x = 0) and for the negative estimates noise can
produce, which the stiffness form cannot represent.

Its derivative with respect to x, used by Gauss-Newton:
``d(dq)/dx = (I - X K_C)^-1 diag(tau)``, tau = J(q+dq)^T w, K_C at q+dq
(eq. 8), and ``d(screw)/d(dq) = [J_v; J_l^-1(phi) J_w]`` at q+dq, where
J_l^-1 is the inverse left Jacobian of SO(3) at the rotation vector phi.
"""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.equilibrium import (
    CHUNK,
    EquilibriumError,
    entry_major_rows,
    newton_deflection_em,
)
from analysis.kinetostatics.small_linalg import diagonally_dominant, lu_em, lu_solve_right_em
from analysis.kinetostatics.stiffness import complementary_stiffness_em
from analysis.model.kinematics import (
    ChainState,
    ChainStateEM,
    chain_state_em,
    jacobian_em,
    joint_cos_sin,
    pose_difference_em,
)
from analysis.model.robot_model import RobotModel


def so3_left_jacobian_inverse(phi: np.ndarray) -> np.ndarray:
    """J_l^-1(phi) (..., 3, 3) for rotation vectors phi (..., 3) (rad).

    ``d phi = J_l^-1(phi) omega`` for a small rotation omega applied on the
    left, exp(omega) exp(phi); series form below 1e-4 rad.
    """
    phi = np.asarray(phi, dtype=float)
    em = _so3_left_jacobian_inverse_em(np.moveaxis(phi.reshape(-1, 3), 0, -1))
    return np.moveaxis(em, -1, 0).reshape(*phi.shape, 3)


def _so3_left_jacobian_inverse_em(phi: np.ndarray) -> np.ndarray:
    """J_l^-1 (3, 3, N) of rotation vectors phi (3, N), entry-major.

    ``I - K/2 + c(theta) K^2`` with K = [phi]x, K^2 = phi phi^T - theta^2 I and
    ``c = 1/theta^2 - (1 + cos theta) / (2 theta sin theta)`` (1/12 + theta^2/720 below
    1e-4 rad).
    """
    t2 = np.einsum("in,in->n", phi, phi)
    th = np.sqrt(t2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    coef = np.where(small, 1.0 / 12.0 + t2 / 720.0,
                    1.0 / ths**2 - (1.0 + np.cos(ths)) / (2.0 * ths * np.sin(ths)))
    out = np.empty((3, 3) + phi.shape[1:])
    for i in range(3):
        j, k = (i + 1) % 3, (i + 2) % 3
        out[i, i] = 1.0 - coef * (phi[j] * phi[j] + phi[k] * phi[k])
        # K[i, j] = -phi_k, K[j, i] = phi_k for the cyclic (i, j, k)
        pp = coef * (phi[i] * phi[j])
        out[i, j] = pp + 0.5 * phi[k]
        out[j, i] = pp - 0.5 * phi[k]
    return out


def solve_deflection_compliance(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-15,
    max_iter: int = 50,
) -> np.ndarray:
    """dq (..., n) (rad) solving ``dq = x * J(q + dq)^T w`` by Newton's method.

    Parameters
    ----------
    q : (..., n) joint angles (rad). x : (n,) or (..., n) joint compliances
        (rad/(N m)), 0 for a rigid joint. w : (..., 6) wrench (N, N m).
    tol : convergence on max |step| (rad).

    Raises
    ------
    EquilibriumError
        Newton's method did not converge for some pose.
    """
    dq, ok = solve_deflection_masked(robot, q, x, w, tol, max_iter)
    if not np.all(ok):
        raise EquilibriumError(
            f"equilibrium did not converge in {max_iter} Newton steps at "
            f"{int(np.sum(~ok))} pose(s): the wrench is too large for these compliances"
        )
    return dq


def solve_deflection_masked(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-15,
    max_iter: int = 50,
    max_deflection: float = 1.0,
    dq0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Like :func:`solve_deflection_compliance`, batched without raising.

    Returns dq (..., n) (rad, 0 where failed) and ``ok`` (...) bool: Newton
    converged (max |step| <= max(tol, 1e-12) at the end) with a finite
    deflection below ``max_deflection`` (rad) and a nonsingular Jacobian.
    Used where some of many campaigns may hold absurd estimates (Monte-Carlo).
    The solver is :func:`analysis.kinetostatics.equilibrium.newton_deflection`.

    ``dq0`` (..., n): a starting guess (the deflection at nearby compliances, or the
    first-order one); the same converged solution with fewer Newton steps. Poses
    where Newton from ``dq0`` fails are solved again from zero, so a guess never
    loses a solution the cold start finds.
    """
    q = np.asarray(q, dtype=float)
    batch, n = q.shape[:-1], q.shape[-1]
    qe = np.ascontiguousarray(q.reshape(-1, n).T)
    xe, we = entry_major_rows(x, batch, n), entry_major_rows(w, batch, 6)
    d0 = None if dq0 is None else entry_major_rows(dq0, batch, n)
    N = qe.shape[1]
    dq, ok = np.empty((n, N)), np.empty(N, dtype=bool)
    for s in range(0, N, CHUNK):
        sl = slice(s, s + CHUNK)
        dq[:, sl], ok[sl] = _solve_em(robot, qe[:, sl], _cols(xe, sl), _cols(we, sl), tol,
                                      max_iter, max_deflection,
                                      None if d0 is None else d0[:, sl])
    return dq.T.reshape(q.shape), ok.reshape(batch)


def _solve_em(robot, q, x, w, tol, max_iter, max_deflection, dq0, keep=None, cos_sin=None,
              state0=None):
    """:func:`solve_deflection_masked` of one block, entry-major (q (n, N)); ``keep``
    (see :func:`newton_deflection_em`) is left empty when some pose was solved again.

    Newton starts from ``dq0``, then poses where it failed start again from zero; without
    ``dq0`` but with ``state0`` (the chain state at q), from zero first (its first step
    made with state0), then from the first-order deflection ``x * J(q)^T w``: at loads
    close to buckling one start can overshoot where the other converges (where both
    converge, they reach the same deflection).
    """
    dq, bad, last = newton_deflection_em(robot, q, x, w, tol, max_iter, dq0, max_deflection,
                                         keep, cos_sin, state0)
    ok = ~bad & (last <= max(tol, 1e-12))
    if (dq0 is not None or state0 is not None) and not np.all(ok):
        if keep is not None:
            keep.clear()
        retry = ~ok
        xr, wr = _cols(x, retry), _cols(w, retry)
        start = None
        if dq0 is None:
            sub = ChainStateEM(*(getattr(state0, f)[..., retry]
                                 for f in ("origins", "axes", "rot", "pos")))
            start = xr * np.einsum("rin,rn->in", jacobian_em(sub), wr)
            start = np.where(np.isfinite(start), start, 0.0)
        base = None if cos_sin is None else (cos_sin[0][:, retry], cos_sin[1][:, retry])
        d2, b2, l2 = newton_deflection_em(robot, q[:, retry], xr, wr, tol, max_iter, start,
                                          max_deflection, cos_sin=base)
        dq[:, retry] = d2
        ok[retry] = ~b2 & (l2 <= max(tol, 1e-12))
    return dq, ok


def _cols(a: np.ndarray, sel) -> np.ndarray:
    """Columns ``sel`` of an entry-major (k, N) array; a (k, 1) column is shared."""
    return a if a.shape[-1] == 1 else a[:, sel]


def model_displacement(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True,
    w_ref: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Exact displacement screw (..., 6) [m; rad] and its derivative (..., 6, n) w.r.t. x.

    The derivative has units m/(rad/(N m)) and rad/(rad/(N m)) and is exact
    (up to the Newton tolerance) at the solved equilibrium. Raises
    :class:`EquilibriumError` where the equilibrium cannot be solved.
    """
    screw, D, ok = model_displacement_masked(robot, q, x, w, with_jacobian, w_ref)
    if not np.all(ok):
        raise EquilibriumError(
            f"equilibrium did not converge at {int(np.sum(~ok))} pose(s): the wrench is too "
            "large for these compliances"
        )
    return screw, D


def model_displacement_masked(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True,
    w_ref: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """:func:`model_displacement` plus ``ok`` (...) bool; values are 0 where not ok.
    ``w_ref``: see :func:`model_displacement_state`."""
    screw, D, ok, _ = model_displacement_state(robot, q, x, w, with_jacobian, w_ref=w_ref)
    return screw, D, ok


def model_displacement_state(
    robot: RobotModel, q: np.ndarray, x: np.ndarray, w: np.ndarray, with_jacobian: bool = True,
    dq0: np.ndarray | None = None, unloaded: dict | None = None,
    w_ref: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray]:
    """:func:`model_displacement_masked` plus the joint deflection dq (..., n) (rad).

    ``w_ref`` (..., 6): the reference readings' wrench (a preload), or None (unloaded
    references). With it, ``w`` is the wrench difference (loaded minus reference, as in
    :class:`~analysis.identification.io.measurements.TestArrays`) and the displacement is
    the screw between the two equilibria, under w_ref and under w + w_ref
    (:func:`_between_equilibria`); dq is the loaded equilibrium's.

    Newton starts from ``dq0`` (e.g. the deflection of the previous Gauss-Newton
    iterate), else from zero, its first step made with the unloaded chain state (needed
    for the screw anyway): that step, ``(I - X K_C(q))^-1 X J(q)^T w``, errs by O(dq^3)
    where the first-order ``X J(q)^T w`` errs by O(dq^2), so most poses converge one
    Newton evaluation earlier.
    ``unloaded``: a dict that receives ``state`` and ``tip``, the chain state at q and
    its tool pose (a caller that also needs J(q) saves recomputing it); when it already
    holds ``tip`` (the same q) and ``dq0`` is given, the unloaded chain is not recomputed.
    Computed entry-major in blocks of :data:`analysis.kinetostatics.equilibrium.CHUNK`
    poses (cache-sized).
    """
    if w_ref is not None and np.any(w_ref):
        return _between_equilibria(robot, q, x, w, w_ref, with_jacobian, dq0, unloaded)
    q = np.asarray(q, dtype=float)
    batch, n = q.shape[:-1], q.shape[-1]
    qe = np.ascontiguousarray(q.reshape(-1, n).T)
    N = qe.shape[1]
    xe, we = entry_major_rows(x, batch, n), entry_major_rows(w, batch, 6)
    d0 = None if dq0 is None else entry_major_rows(dq0, batch, n)
    reuse = unloaded is not None and "tip" in unloaded and dq0 is not None
    tip0 = np.reshape(unloaded["tip"], (N, 4, 4)) if reuse else np.empty((N, 4, 4))
    keep_state = unloaded is not None and not reuse
    if keep_state:
        origins, axes = np.empty((N, n, 3)), np.empty((N, n, 3))
    screw, ok, dq = np.empty((N, 6)), np.empty(N, dtype=bool), np.empty((N, n))
    D = np.empty((N, 6, n)) if with_jacobian else None
    for s in range(0, N, CHUNK):
        sl = slice(s, s + CHUNK)
        base = joint_cos_sin(qe[:, sl])
        s0 = None
        if not reuse:
            s0 = chain_state_em(robot, qe[:, sl], base)
            tip0[sl] = s0.tip()
            if keep_state:
                origins[sl], axes[sl] = s0.origins.T, s0.axes.T
        d0s = None if d0 is None else d0[:, sl]
        screw[sl], ok[sl], dq[sl], Db = _model_block(
            robot, qe[:, sl], _cols(xe, sl), _cols(we, sl), with_jacobian,
            None if d0s is None else np.where(np.isfinite(d0s), d0s, 0.0), tip0[sl], base, s0)
        if with_jacobian:
            D[sl] = Db
    if keep_state:
        unloaded.update(state=ChainState(origins.reshape(*batch, n, 3),
                                         axes.reshape(*batch, n, 3),
                                         tip0.reshape(*batch, 4, 4)),
                        tip=tip0.reshape(*batch, 4, 4))
    return (screw.reshape(*batch, 6), None if D is None else D.reshape(*batch, 6, n),
            ok.reshape(batch), dq.reshape(q.shape))


def _rotation_matrices(phi: np.ndarray) -> np.ndarray:
    """exp([phi]x) (N, 3, 3) of rotation vectors phi (N, 3) (rad), Rodrigues."""
    t = np.sqrt(np.sum(phi * phi, axis=-1))[:, None, None]
    K = np.zeros((len(phi), 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -phi[:, 2], phi[:, 1], -phi[:, 0]
    K[:, 1, 0], K[:, 2, 0], K[:, 2, 1] = phi[:, 2], -phi[:, 1], phi[:, 0]
    ts = np.where(t > 0, t, 1.0)
    a = np.where(t > 1e-6, np.sin(ts) / ts, 1.0 - t**2 / 6)
    b = np.where(t > 1e-6, (1.0 - np.cos(ts)) / ts**2, 0.5 - t**2 / 24)
    return np.eye(3) + a * K + b * (K @ K)


def _between_equilibria(robot, q, x, w, w_ref, with_jacobian, dq0, unloaded):
    """The displacement of P between the equilibrium under w_ref (the reference reading)
    and under w + w_ref (the loaded one), ``w`` being the wrench difference, with its
    derivative w.r.t. x: translations subtract; the rotation is log(R_L R_R^T), whose
    left-trivialised derivative is omega_L - R_rel omega_R (omega = J_l(phi) times the
    rotation rows of each equilibrium's derivative), mapped by J_l^-1 of the result."""
    from analysis.model.kinematics import rotation_vector

    w = np.asarray(w, dtype=float)
    w_ref = np.broadcast_to(np.asarray(w_ref, dtype=float), w.shape)
    fL, DL, okL, dqL = model_displacement_state(robot, q, x, w + w_ref, with_jacobian, dq0,
                                                unloaded)
    fR, DR, okR, _ = model_displacement_state(robot, q, x, w_ref, with_jacobian)
    batch = fL.shape[:-1]
    fL2, fR2 = fL.reshape(-1, 6), fR.reshape(-1, 6)
    RL, RR = _rotation_matrices(fL2[:, 3:]), _rotation_matrices(fR2[:, 3:])
    rel = RL @ np.swapaxes(RR, -1, -2)
    screw = np.empty(fL2.shape)
    screw[:, :3] = fL2[:, :3] - fR2[:, :3]
    screw[:, 3:] = rotation_vector(rel)
    ok = (okL & okR).reshape(-1)
    D = None
    if with_jacobian:
        n = DL.shape[-1]
        DL2, DR2 = DL.reshape(-1, 6, n), DR.reshape(-1, 6, n)
        Jl = np.linalg.inv(so3_left_jacobian_inverse(fL2[:, 3:]))
        Jr = np.linalg.inv(so3_left_jacobian_inverse(fR2[:, 3:]))
        omega = Jl @ DL2[:, 3:] - rel @ (Jr @ DR2[:, 3:])
        D = np.empty(DL2.shape)
        D[:, :3] = DL2[:, :3] - DR2[:, :3]
        D[:, 3:] = so3_left_jacobian_inverse(screw[:, 3:]) @ omega
        D[~ok] = 0.0
        D = D.reshape(*batch, 6, n)
    screw[~ok] = 0.0
    return screw.reshape(*batch, 6), D, ok.reshape(batch), dqL


def _model_block(robot, q, x, w, with_jacobian, dq0, tip0, base, state0):
    """Screw (N, 6), ok (N,), dq (N, n) and the derivative (N, 6, n) or None of one block
    of :func:`model_displacement_state`: q, x, dq0 (n, N) (None: from zero), w (6, N),
    tip0 (N, 4, 4) the unloaded tool poses, base (cos q, sin q), state0 the unloaded
    chain state (or None)."""
    n = q.shape[0]
    keep: dict = {}
    dq, ok = _solve_em(robot, q, x, w, 1e-15, 50, 1.0, dq0, keep, base, state0)
    last_step = None
    if keep:
        # Newton's last evaluated iterate dq_k: its state, J, J^T w, I - X K_C and the LU
        # factors of the latter are already computed; the returned dq is dq_k minus the
        # last step (<= 1e-15 rad), which the screw follows to first order below
        dqk, s1, J1, tau, M, LU = (keep[k] for k in ("dq", "state", "J", "tau", "dF", "lu"))
        last_step = np.where(ok, dq - dqk, 0.0)
        dq = np.where(ok, dq, 0.0)
    else:
        s1 = chain_state_em(robot, q, joint_cos_sin(q, dq, base))
        J1 = jacobian_em(s1)
        tau = np.einsum("rin,rn->in", J1, w)
        M = LU = None
    screw = pose_difference_em(np.moveaxis(tip0[:, :3, :3], 0, -1), tip0[:, :3, 3].T,
                               s1.rot, s1.pos)
    Dd = None
    if with_jacobian:  # D = d screw / d dq = [J_v; J_l^-1 J_w], (6, n, N)
        Dd = J1.copy()
        Jl = _so3_left_jacobian_inverse_em(np.ascontiguousarray(screw[:, 3:].T))
        Dd[3:] = _matmul_em(Jl, J1[3:])
    if last_step is not None:
        # screw(dq) = screw(dq_k) + D (dq - dq_k) + O(step^2); without the model Jacobian
        # J stands for D: J_l^-1 = I + O(|phi|) changes a correction of <= 1e-15 rad by
        # |phi|/2 of it
        screw += np.einsum("rin,in->nr", J1 if Dd is None else Dd, last_step)
    if not ok.all():
        screw[~ok] = 0.0
    if not with_jacobian:
        return screw, ok, dq.T, None
    if LU is None:
        if M is None:
            M = -x[:, None] * complementary_stiffness_em(J1, w)
            M[np.arange(n), np.arange(n)] += 1.0  # I - X K_C, rounded as 1 - x K
        if not ok.all():
            M = np.where(ok, M, np.eye(n)[:, :, None])
        if diagonally_dominant(M).all():  # I - X K_C at ordinary loads
            LU = lu_em(M.copy())
    # D (I - X K_C)^-1 diag(tau): d dq / dx = (I - X K_C)^-1 diag(tau)
    if LU is not None:
        G = lu_solve_right_em(LU, Dd)
    else:  # not diagonally dominant: LAPACK with partial pivoting
        G = np.moveaxis(np.swapaxes(np.linalg.solve(
            np.swapaxes(np.moveaxis(M, -1, 0), -1, -2),
            np.swapaxes(np.moveaxis(Dd, -1, 0), -1, -2)), -1, -2), 0, -1)
    out = G * tau[None]
    if not ok.all():
        out[:, :, ~ok] = 0.0
    return screw, ok, dq.T, np.moveaxis(out, -1, 0)


def _matmul_em(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """A B for entry-major A (p, k, N) and B (k, r, N) -> (p, r, N)."""
    out = A[:, 0, None] * B[0][None]
    for j in range(1, A.shape[1]):
        out += A[:, j, None] * B[j][None]
    return out
