"""The nonlinear elastostatic equilibrium and the finite displacement it produces.

``K_theta dq = J(q + dq)^T w`` is solved by Newton's method, batched over poses;
its Jacobian is ``K_theta - K_C(q + dq)``. This is the model the simulated lab
uses and the exact identification fits; the linear model of eq. 14 is its
first-order approximation.
"""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.small_linalg import lu_em, lu_solve_em, solve_dominant
from analysis.kinetostatics.stiffness import (
    complementary_stiffness_em,
    complementary_stiffness_from_jacobian,
)
from analysis.model.kinematics import (
    ChainStateEM,
    chain_state,
    chain_state_em,
    jacobian,
    jacobian_em,
    joint_cos_sin,
    pose_difference,
)
from analysis.model.robot_model import RobotModel


class EquilibriumError(RuntimeError):
    """Newton's method did not converge (load close to buckling the model).

    ``unconverged`` is a boolean mask over the batch (poses whose last step
    was still above the tolerance), or None.
    """

    def __init__(self, message: str, unconverged: np.ndarray | None = None) -> None:
        super().__init__(message)
        self.unconverged = unconverged


#: poses per block of the entry-major Newton solve: the working set of a block (J, K_C,
#: the Newton matrix: ~100 vectors of CHUNK doubles) stays in a 2 MB L2 cache, where the
#: element-wise work is ~3x cheaper than on blocks of 8192 poses
CHUNK = 2048


def newton_deflection(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-14,
    max_iter: int = 50,
    dq0: np.ndarray | None = None,
    max_deflection: float = np.inf,
    keep: dict | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The one Newton solver of the equilibrium, batched, in joint compliances; never raises.

    Solves ``F(dq) = dq - x * J(q + dq)^T w = 0`` (``K_theta dq = J^T w``
    multiplied by ``X = K_theta^-1``: the same Newton steps as the stiffness
    form, ``(K_theta - K_C)^-1 (K_theta dq - J^T w)``, and defined for rigid
    joints, x = 0). Its Jacobian is ``I - X K_C(q + dq)``.

    Parameters
    ----------
    q : (..., n) joint angles (rad). x : (n,) or (..., n) joint compliances
        (rad/(N m)). w : (..., 6) wrench [f (N); m (N m)] at P, base frame.
    tol : a pose has converged when its last max |step| <= tol (rad; relative to
        max |dq| when that exceeds 1 rad); iteration
        stops when every pose (of a block of :data:`CHUNK`) has converged or failed.
    dq0 : (..., n) starting guess (rad), zero if None.
    max_deflection : a pose whose |dq| exceeds this (rad) is marked failed.

    Returns
    -------
    dq : (..., n) deflection (rad), 0 where failed.
    failed : (...) bool, singular Newton matrix, non-finite or too large deflection.
    last_step : (...) last max |step| of each pose (rad), divided by max |dq| when that
        exceeds 1 rad; inf where failed.

    ``keep``: a dict to receive the last iterate the Newton matrix was evaluated at,
    ``dq`` (..., n), with its ``state`` (:class:`ChainState` at q + dq), ``J`` (..., 6, n)
    and ``dF`` (..., n, n) = I - X K_C there (I where failed). That iterate is as
    converged as the returned dq (they differ by the last step, at most ``tol``), and
    a caller that needs the state, J or K_C at the solution saves recomputing them.
    The work is done block by block by :func:`newton_deflection_em`.
    """
    q = np.asarray(q, dtype=float)
    batch, n = q.shape[:-1], q.shape[-1]
    qe = np.ascontiguousarray(q.reshape(-1, n).T)
    N = qe.shape[1]
    xe = entry_major_rows(x, batch, n)
    we = entry_major_rows(w, batch, 6)
    d0 = None if dq0 is None else entry_major_rows(dq0, batch, n)
    dq, bad, last = np.empty((n, N)), np.empty(N, dtype=bool), np.empty(N)
    parts: list = []
    for s in range(0, max(N, 1), CHUNK):  # one (empty) block for an empty batch
        sl = slice(s, s + CHUNK)
        part: dict | None = {} if keep is not None else None
        dq[:, sl], bad[sl], last[sl] = newton_deflection_em(
            robot, qe[:, sl], _cols(xe, sl), _cols(we, sl), tol, max_iter,
            None if d0 is None else d0[:, sl], max_deflection, part)
        parts.append(part)
    if keep is not None:
        keep.update(dq=np.concatenate([p["dq"] for p in parts], axis=-1).T.reshape(q.shape),
                    state=_concat_states(parts).batch_first(batch),
                    J=_batch_first(np.concatenate([p["J"] for p in parts], axis=-1), batch),
                    dF=_batch_first(np.concatenate([p["dF"] for p in parts], axis=-1), batch))
    return dq.T.reshape(q.shape), bad.reshape(batch), last.reshape(batch)


def newton_deflection_em(
    robot: RobotModel,
    q: np.ndarray,
    x: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-14,
    max_iter: int = 50,
    dq0: np.ndarray | None = None,
    max_deflection: float = np.inf,
    keep: dict | None = None,
    cos_sin: tuple[np.ndarray, np.ndarray] | None = None,
    state0: ChainStateEM | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`newton_deflection` on N poses entry-major, in one block.

    q (n, N) (rad); x (n, 1) or (n, N); w (6, 1) or (6, N); dq0 (n, N) or None.
    Returns dq (n, N), failed (N,), last_step (N,). ``keep`` receives entry-major
    ``dq`` (n, N), ``state`` (:class:`ChainStateEM`), ``J`` (6, n, N), ``tau`` (n, N)
    = J^T w and ``dF`` (n, n, N), each pose's at the last iterate evaluated for it, and
    ``lu``, the :func:`analysis.kinetostatics.small_linalg.lu_em` factors of dF (None when
    some dF was not diagonally dominant and went to LAPACK).
    ``cos_sin``: (cos q, sin q) when the caller has them; ``state0``: the chain state at q
    (used when ``dq0`` is None: the first iterate, dq = 0, is q itself).

    A pose stops iterating once it has converged or failed (the others go on): its
    deflection is the one it had then, within its last step (<= tol) of where further
    steps would take it.
    """
    n, N = q.shape
    dq = np.zeros((n, N)) if dq0 is None else np.array(dq0, dtype=float)
    bad = np.zeros(N, dtype=bool)
    last = np.full(N, np.inf)
    base = joint_cos_sin(q) if cos_sin is None else cos_sin
    kept = _Kept(state0) if keep is not None else None
    act = None  # indices of the poses still iterating; None: all of them
    qa, xa, wa, ca, sa, da = q, x, w, base[0], base[1], dq
    diag = (np.arange(n), np.arange(n))
    for it in range(max_iter):
        if it == 0 and dq0 is None:
            state = state0 if state0 is not None else chain_state_em(robot, qa, (ca, sa))
        else:
            state = chain_state_em(robot, qa, joint_cos_sin(qa, da, (ca, sa)))
        J = jacobian_em(state)
        tau = np.einsum("rin,rn->in", J, wa)
        F = da - xa * tau
        dF = complementary_stiffness_em(J, wa)
        np.multiply(dF, -xa[:, None], out=dF)
        dF[diag] += 1.0  # I - X K_C, rounded as 1 - x K
        dominant, bad_a = _dominance(dF)  # bad: non-finite or singular
        if bad_a.any():
            dF[:, :, bad_a] = np.eye(n)[:, :, None]
            F[:, bad_a] = 0.0
        if (dominant | bad_a).all():  # the usual case: LU without pivoting, kept
            LU = lu_em(dF.copy())
            step = lu_solve_em(LU, F[:, None, :])[:, 0]
        else:
            LU, step = None, solve_dominant(dF, F, dominant | bad_a)
        if kept is not None:
            kept.record(act, N, dq=da, state=state, J=J, tau=tau, dF=dF, lu=LU)
        da = da - step
        size = np.max(np.abs(da), axis=0, initial=0.0)
        bad_a |= ~np.isfinite(da).all(axis=0) | (size > max_deflection)
        if bad_a.any():
            da[:, bad_a] = 0.0
            size[bad_a] = 0.0
        # relative to the deflection once it exceeds 1 rad: rounding keeps the step of a
        # converged large deflection above an absolute 1e-14 rad
        last_a = np.where(bad_a, np.inf, np.max(np.abs(step), axis=0, initial=0.0)
                          / np.maximum(1.0, size))
        if act is None:
            dq, bad, last = da, bad_a, last_a
        else:
            dq[:, act], bad[act], last[act] = da, bad_a, last_a
        done = bad_a | (last_a <= tol)
        if done.all():
            break
        if done.any():
            go = ~done
            act = np.flatnonzero(go) if act is None else act[go]
            qa, ca, sa, da = qa[:, go], ca[:, go], sa[:, go], da[:, go]
            xa = xa if xa.shape[-1] == 1 else xa[:, go]
            wa = wa if wa.shape[-1] == 1 else wa[:, go]
    if kept is not None:
        keep.update(kept.arrays)
    return dq, bad, last


class _Kept:
    """The last iterate evaluated for each pose and its state, J, J^T w and Newton matrix.

    The arrays of an iteration over every pose are kept as they are (each iteration makes
    new ones); later iterations over fewer poses write into them, after copying the
    caller's ``shared`` state if it is among them.
    """

    def __init__(self, shared: ChainStateEM | None = None) -> None:
        self.arrays: dict = {}
        self.shared = shared

    def record(self, act, N, **arrays) -> None:
        if act is None:  # every pose: the arrays themselves
            self.arrays = arrays
            return
        state = self.arrays.get("state")
        if state is not None and state is self.shared:
            self.arrays["state"] = ChainStateEM(*(getattr(state, f).copy()
                                                  for f in ("origins", "axes", "rot", "pos")))
        for k, v in arrays.items():
            if v is None or self.arrays[k] is None:
                self.arrays[k] = None
            elif k == "state":
                for f in ("origins", "axes", "rot", "pos"):
                    getattr(self.arrays[k], f)[..., act] = getattr(v, f)
            else:
                self.arrays[k][..., act] = v


def entry_major_rows(a: np.ndarray, batch: tuple, k: int) -> np.ndarray:
    """(k, N) contiguous rows of ``a`` broadcast to (*batch, k), N = prod(batch);
    (k, 1) when ``a`` is one (k,) vector for the whole batch."""
    a = np.asarray(a, dtype=float)
    if a.ndim == 1:
        return a[:, None]
    return np.ascontiguousarray(np.broadcast_to(a, (*batch, k)).reshape(-1, k).T)


def _cols(a: np.ndarray, sl: slice) -> np.ndarray:
    return a if a.shape[-1] == 1 else a[:, sl]


def _batch_first(a: np.ndarray, batch: tuple) -> np.ndarray:
    return np.ascontiguousarray(np.moveaxis(a, -1, 0)).reshape(*batch, *a.shape[:-1])


def _concat_states(parts: list) -> ChainStateEM:
    return ChainStateEM(*(np.concatenate([getattr(p["state"], f) for p in parts], axis=-1)
                          for f in ("origins", "axes", "rot", "pos")))


def _dominance(dF: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry-major dF (n, n, N) -> (strictly row diagonally dominant, bad), (N,) bool.

    Bad: some entry is not finite, or |det dF| < 1e-12 (the Newton matrix is singular to
    working precision). I - X K_C is strictly diagonally dominant at ordinary loads, and
    then |det| >= prod_i (|a_ii| - sum_j!=i |a_ij|) (Ostrowski): the determinant is
    computed only where that bound does not already exceed the threshold. A non-finite
    entry makes its row's margin non-finite (inf or nan), so the margins tell both.
    """
    n = dF.shape[0]
    A = np.abs(dF)
    margin = 2.0 * A[np.arange(n), np.arange(n)] - A.sum(axis=1)  # (n, N)
    finite = np.isfinite(margin).all(axis=0)
    dominant = np.all(margin > 0, axis=0)
    check = finite & ~(dominant & (np.prod(np.maximum(margin, 0.0), axis=0) >= 1e-12))
    bad = ~finite
    if np.any(check):
        bad[check] = np.abs(np.linalg.det(np.moveaxis(dF[:, :, check], -1, 0))) < 1e-12
    return dominant, bad


def solve_deflection(
    robot: RobotModel,
    q: np.ndarray,
    k: np.ndarray,
    w: np.ndarray,
    tol: float = 1e-14,
    max_iter: int = 50,
    dq0: np.ndarray | None = None,
) -> np.ndarray:
    """Joint deflection dq (..., n) (rad) solving K_theta dq = J(q + dq)^T w.

    Parameters
    ----------
    q : (..., n) joint angles (rad); k : (n,) or (..., n) joint stiffness (N m/rad);
    w : (..., 6) wrench [f (N); m (N m)] at P, base frame.
    tol : convergence on max |step| (rad), relative to max |dq| when that exceeds 1 rad.
    dq0 : (..., n) starting guess (rad), e.g. the solution at a nearby pose; zero if None.

    Raises
    ------
    EquilibriumError
        Some pose did not converge in ``max_iter`` steps (or its Newton matrix
        is singular); ``unconverged`` masks those poses.
    """
    x = 1.0 / np.asarray(k, dtype=float)
    dq, bad, last = newton_deflection(robot, q, x, w, tol, max_iter, dq0)
    unconverged = bad | (last > tol)
    if np.any(unconverged):
        worst = np.max(np.where(np.isfinite(last), last, np.inf))
        raise EquilibriumError(
            f"equilibrium did not converge in {max_iter} Newton steps (last step "
            f"{worst:.3g} rad): the wrench is too large for this stiffness",
            unconverged=unconverged,
        )
    return dq


def displacement_screw(
    robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray
) -> np.ndarray:
    """Finite displacement of P under w: [p(q+dq) - p(q) (m); rotvec(R(q+dq) R(q)^T) (rad)]."""
    q = np.asarray(q, dtype=float)
    dq = solve_deflection(robot, q, k, w)
    t0 = chain_state(robot, q).tip
    t1 = chain_state(robot, q + dq).tip
    return pose_difference(t0, t1)


def deflection_with_joint_torques(robot: RobotModel, q: np.ndarray, k: np.ndarray,
                                  w: np.ndarray, torques, tol: float = 1e-14,
                                  max_iter: int = 60) -> np.ndarray:
    """Joint deflection dq (N, n) (rad) solving ``K_theta dq = J(theta)^T w + tau(theta)``
    at theta = q + dq, for joint torques that depend on the pose (gravity, a gravity
    compensator's spring): the equilibrium of :func:`newton_deflection` with one more
    term, solved by Newton's method in the compliance form.

    ``q`` (N, n) rad, ``k`` (n,) N m/rad, ``w`` (N, 6) [f (N); m (N m)] at P, base
    frame; ``torques(theta)`` returns tau (N, n) (N m) and its derivative
    d tau / d theta (N, n, n) (N m/rad). Raises :class:`EquilibriumError` when a pose
    has not converged after ``max_iter`` steps. One case of
    :func:`deflection_with_joint_torques_cases`.
    """
    return deflection_with_joint_torques_cases(
        robot, q[None], np.asarray(k, dtype=float)[None], np.asarray(w, dtype=float)[None],
        lambda theta, live: torques(theta), tol, max_iter)[0]


def deflection_with_joint_torques_cases(robot: RobotModel, q: np.ndarray, k: np.ndarray,
                                        w: np.ndarray, torques, tol: float = 1e-14,
                                        max_iter: int = 60) -> np.ndarray:
    """:func:`deflection_with_joint_torques` of C independent cases at once: dq (C, N, n)
    (rad) for q (C, N, n) (rad), k (C, n) (N m/rad), w (C, N, 6) [N; N m];
    ``torques(theta, live)`` returns tau (c N, n) (N m) and d tau / d theta (c N, n, n)
    (N m/rad) at theta (c N, n), the poses of the cases ``live`` (c,) (indices, ascending)
    stacked case after case.

    Each case iterates until its own poses have converged and is then left alone, so a
    case's numbers are those of its own call of :func:`deflection_with_joint_torques`
    (one Python loop for many cases: the finite differences of a fit). Raises
    :class:`EquilibriumError` for the first case (lowest index) that did not converge.
    """
    C, N, n = q.shape
    x = 1.0 / np.asarray(k, dtype=float)  # (C, n)
    dq = np.zeros((C, N, n))
    step = np.full((C, N), np.inf)
    live = np.arange(C)
    failed = np.zeros(C, dtype=bool)
    for _ in range(max_iter):
        c = live.size
        theta = (q[live] + dq[live]).reshape(c * N, n)
        J = jacobian(robot, theta)
        extra, dextra = torques(theta, live)
        wl = w[live].reshape(c * N, 6)
        xl = np.repeat(x[live], N, axis=0)  # (c N, n)
        tau = np.einsum("pri,pr->pi", J, wl) + extra
        dtau = complementary_stiffness_from_jacobian(J, wl) + dextra
        dql = dq[live].reshape(c * N, n)
        F = dql - xl * tau
        dF = np.eye(n) - xl[:, :, None] * dtau
        delta = np.linalg.solve(dF, F[..., None])[..., 0]
        dql = (dql - delta).reshape(c, N, n)
        dq[live] = dql
        st = np.max(np.abs(delta), axis=-1).reshape(c, N)
        step[live] = st
        bad = ~np.all(np.isfinite(dql), axis=(1, 2))
        done = np.all(st <= tol * np.maximum(1.0, np.max(np.abs(dql), axis=-1)), axis=1)
        failed[live[bad]] = True
        live = live[~bad & ~done]
        if live.size == 0:
            break
    failed[live] = True
    if np.any(failed):
        first = int(np.flatnonzero(failed)[0])
        raise EquilibriumError(
            f"equilibrium with pose-dependent joint torques did not converge in {max_iter} "
            f"Newton steps (last step {np.nanmax(step[first]):.3g} rad)",
            unconverged=~(step[first] <= tol))
    return dq
