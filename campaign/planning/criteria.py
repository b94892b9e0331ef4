"""Design information under the identification's noise model, and the worst-joint criterion.

Information of one candidate test
---------------------------------
The identification weights each test row by the inverse of its residual
covariance (:func:`analysis.identification.noise.residual_covariance`):
displacement noise (tracker, rotation from the reflector fit) plus the F/T
noise propagated through the Cartesian compliance ``C = J K^-1 J^T`` at the
reading, plus (for the prediction of a chosen design) the encoder noise
through the derivative of the displacement with respect to the joint angles.
A test of ``rows`` independent repeats has the information
``rows * B^T B`` with ``B = L^-1 A diag(1/k0)`` (``L L^T = Sigma``), i.e. the
information of the *relative* compliances ``x / x0``; its inverse is their
covariance, and ``sqrt(diag(M^-1))`` is the relative standard error of each
k (delta method, ``se_k / k = se_x / x``), evaluated at the prior stiffness.

Criteria (smaller is better here, unlike :func:`campaign.planning.design.criterion`)
--------------------------------------------------------------------------
``worst``: the largest relative standard error over the joints (the user's
question "how well is the worst joint known?"), optionally with guards
``g_j``: a joint whose relative se exceeds its guard multiplies the
objective by ``1 + 10 * sum(excess)``, so the worst joint is not bought by
giving up another joint. ``weighted``: the user-weighted sum of the
relative standard errors.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.linear_model import design_block
from analysis.identification.noise import NoiseModel, residual_covariance
from campaign.planning.design import greedy_exchange, information, random_design, zones_of
from campaign.planning.separation import Separation, blocked

GUARD_PENALTY = 10.0
BLOCK = 4096  # poses per block of candidate_information
TIE_BREAK = 0.1
#: candidates evaluated exactly per exchange step (the rest screened by a first-order gain)
SCREEN = 384
#: guards are this fraction of the random designs' median relative se (margin for the
#: Monte-Carlo spread and the encoder term the criterion leaves out)
GUARD_FRACTION = 0.95


def candidate_information(
    J: np.ndarray,
    wrenches: np.ndarray,
    noise: NoiseModel,
    k_prior: np.ndarray,
    rows: int = 1,
    dJ: np.ndarray | None = None,
    compliance: np.ndarray | None = None,
) -> np.ndarray:
    """Information (..., n, n) of the relative compliances for tests (J, w) of ``rows`` repeats.

    Parameters
    ----------
    J : (..., 6, n) Jacobians at P (m/rad, rad/rad). wrenches : (..., 6) (N, N m), base frame.
    noise : noise model of one test row. k_prior : (n,) prior stiffness (N m/rad).
    rows : independent repeats of each test. dJ : (..., 6, n, n) dJ/dq (last axis the
        joint differentiated), for the encoder term; left out when None.
    compliance : (..., 6, 6) :func:`cartesian_compliance` of J when the caller has it
        (tests sharing a pose share it); computed here when None.
    """
    w = np.broadcast_to(np.asarray(wrenches, dtype=float), (*J.shape[:-2], 6))
    if J.ndim == 3 and J.shape[0] > BLOCK:
        # blocks of poses with BLAS on one thread: small products on huge batches
        # otherwise hit BLAS threading (as campaign.planning.design.information_of_tests)
        from threadpoolctl import threadpool_limits

        out = np.empty((J.shape[0], J.shape[-1], J.shape[-1]))
        with threadpool_limits(limits=1):
            for lo in range(0, J.shape[0], BLOCK):
                sl = slice(lo, lo + BLOCK)
                out[sl] = candidate_information(
                    J[sl], w[sl], noise, k_prior, rows, None if dJ is None else dJ[sl],
                    None if compliance is None else compliance[sl])
        return out
    x0 = 1.0 / np.asarray(k_prior, dtype=float)
    A = design_block(J, w)
    C = cartesian_compliance(J, k_prior) if compliance is None else compliance
    G = None if dJ is None else encoder_gradient(J, dJ, w, x0)
    S = residual_covariance(noise, C, w, G)
    if S.ndim == 3:
        # whitening L^-1 A by an entry-major Cholesky and forward substitution over the
        # whole batch: one LAPACK call per 6 x 6 matrix (np.linalg.solve) costs ~4x more
        from analysis.identification.linalg.batch_lsq import cholesky, forward_substitute

        B = np.moveaxis(forward_substitute(cholesky(np.moveaxis(S, 0, -1)),
                                           np.moveaxis(A, 0, -1)), -1, 0) * x0
    else:
        B = np.linalg.solve(np.linalg.cholesky(S), A) * x0
    return rows * information(B)


def encoder_gradient(J: np.ndarray, dJ: np.ndarray, w: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """G (..., 6, n): derivative of the model displacement J X J^T w with respect to the
    joint angles (m/rad, rad/rad) at compliances x0 (n,) (rad/(N m)); J (..., 6, n),
    dJ (..., 6, n, n) (last axis the joint differentiated), w (..., 6) (N, N m)."""
    # d(J X J^T w)/dq_k = dJ_k X J^T w + J X dJ_k^T w
    tau = np.einsum("...ji,...j->...i", J, w)
    dtau = np.einsum("...jik,...j->...ik", dJ, w)
    return np.einsum("...rik,...i->...rk", dJ, x0 * tau) + np.einsum(
        "...ri,...ik->...rk", J * x0, dtau)


def cartesian_compliance(J: np.ndarray, k_prior: np.ndarray) -> np.ndarray:
    """C = J K^-1 J^T (..., 6, 6) (m/N, rad/(N m), ...) for Jacobians J (..., 6, n) at P."""
    x0 = 1.0 / np.asarray(k_prior, dtype=float)
    return np.einsum("...ij,j,...kj->...ik", J, x0, J)


def pose_compliance(J: np.ndarray, k_prior: np.ndarray) -> np.ndarray:
    """:func:`cartesian_compliance` of every pose of J (N, 6, n), in blocks of :data:`BLOCK`."""
    out = np.empty((J.shape[0], 6, 6))
    for lo in range(0, J.shape[0], BLOCK):
        out[lo:lo + BLOCK] = cartesian_compliance(J[lo:lo + BLOCK], k_prior)
    return out


def tests_information(
    J: np.ndarray,
    pose: np.ndarray,
    wrenches: np.ndarray,
    case: np.ndarray | None,
    noise: NoiseModel,
    k_prior: np.ndarray,
    rows: int = 1,
    compliance: np.ndarray | None = None,
) -> np.ndarray:
    """Information (T, n, n) of T candidate tests, each a pose of J under a load case.

    Equal to ``candidate_information(J[pose], wrenches[case], ...)`` (``wrenches`` itself,
    one (6,) wrench for every test, when ``case`` is None), computed in the same blocks of
    :data:`BLOCK` tests, but each block gathers its own Jacobians and wrenches: the
    (T, 6, n) copy of ``J[pose]`` (~110 MB at 1e5 candidates of four load cases) and its
    page faults are never made; the Cartesian compliance is computed once per pose
    (``compliance``, :func:`pose_compliance` of J, when the caller has it), not per test.

    Parameters
    ----------
    J : (N, 6, n) Jacobians of the candidate poses (m/rad, rad/rad). pose : (T,) index into J.
    wrenches : (m, 6) load cases (N, N m), or (6,) with ``case`` None. case : (T,) index or None.
    noise, k_prior, rows : as :func:`candidate_information`.
    compliance : (N, 6, 6) :func:`pose_compliance` of J, or None.
    """
    from threadpoolctl import threadpool_limits

    pose = np.asarray(pose)
    out = np.empty((pose.size, J.shape[-1], J.shape[-1]))
    with threadpool_limits(limits=1):
        C = pose_compliance(J, k_prior) if compliance is None else compliance
        for lo in range(0, pose.size, BLOCK):
            sl = slice(lo, lo + BLOCK)
            w = wrenches if case is None else wrenches[case[sl]]
            out[sl] = candidate_information(J[pose[sl]], w, noise, k_prior, rows,
                                            compliance=C[pose[sl]])
    return out


def relative_se(M: np.ndarray) -> np.ndarray:
    """Relative standard errors (..., n) of k for information M (..., n, n); inf if singular."""
    M = np.asarray(M, dtype=float)
    n = M.shape[-1]
    # scale to unit diagonal so that the singularity test does not depend on units
    s = np.sqrt(np.abs(np.diagonal(M, axis1=-2, axis2=-1)))
    s = np.where(s > 0, s, 1.0)
    Ms = M / s[..., :, None] / s[..., None, :]
    sign, logdet = np.linalg.slogdet(Ms)
    good = (sign > 0) & (logdet > -32.0 * n)  # det of the unit-diagonal form below ~1e-14^n
    safe = np.where(good[..., None, None], Ms, np.eye(n))
    d = np.diagonal(np.linalg.inv(safe), axis1=-2, axis2=-1) / s**2
    good &= np.all(d > 0, axis=-1)
    return np.where(good[..., None], np.sqrt(np.abs(d)), np.inf)


def objective(
    M: np.ndarray,
    kind: str = "worst",
    weights: np.ndarray | None = None,
    guard: np.ndarray | None = None,
) -> np.ndarray:
    """Criterion (...) of information matrices M (..., n, n); smaller is better.

    ``worst``: max_j rel_se_j, times ``1 + GUARD_PENALTY * sum_j max(0, rel_se_j / g_j - 1)``
    with guards ``guard`` (n,) when given. ``weighted``: sum_j weights_j rel_se_j.
    """
    return objective_of_se(relative_se(M), kind, weights, guard)


def objective_of_se(
    r: np.ndarray,
    kind: str = "worst",
    weights: np.ndarray | None = None,
    guard: np.ndarray | None = None,
) -> np.ndarray:
    """:func:`objective` of relative standard errors r (..., n) (dimensionless) already
    computed (the model-class planner's marginal ones, :mod:`campaign.planning.model_class`)."""
    if kind == "weighted":
        wts = np.ones(r.shape[-1]) if weights is None else np.asarray(weights, float)
        return np.sum(r * wts, axis=-1)
    if kind != "worst":
        raise ValueError(f"unknown criterion {kind!r}")
    # the mean breaks ties among designs with the same worst joint, so that the
    # other joints are not left at their guard
    out = np.max(r, axis=-1) + TIE_BREAK * np.mean(r, axis=-1)
    if guard is not None:
        with np.errstate(invalid="ignore"):
            excess = np.sum(np.maximum(r / guard - 1.0, 0.0), axis=-1)
        out = out * (1.0 + GUARD_PENALTY * np.where(np.isfinite(excess), excess, np.inf))
    return out


def exchange(
    F: np.ndarray,
    group: np.ndarray,
    start: np.ndarray,
    kind: str = "worst",
    weights: np.ndarray | None = None,
    guard: np.ndarray | None = None,
    max_passes: int = 20,
    rel_tol: float = 1e-6,
    sep: Separation | None = None,
) -> tuple[np.ndarray, float]:
    """Exchange passes from ``start`` minimising :func:`objective` (one candidate per group).

    Each slot in turn is swapped for the allowed candidate that gives the
    smallest criterion, evaluated exactly over all candidates (batched
    inverses of n x n matrices); stops when a pass improves nothing by more
    than ``rel_tol``. ``sep``: the poses' minimum separation (:mod:`campaign.planning.separation`).
    Returns sorted picks and their criterion.
    """
    chosen = [int(c) for c in start]
    M = F[chosen].sum(axis=0)
    current = float(objective(M, kind, weights, guard))
    for _ in range(max_passes):
        improved = False
        for slot in range(len(chosen)):
            base = M - F[chosen[slot]]
            others = [c for j, c in enumerate(chosen) if j != slot]
            allowed = ~blocked(group, others, sep) if others else np.ones(len(F), bool)
            idx = _screen(base, F, allowed, kind, weights, guard)
            if not idx.size:
                continue
            score = objective(base + F[idx], kind, weights, guard)
            j = int(np.argmin(score))
            if score[j] < current * (1 - rel_tol):
                chosen[slot] = int(idx[j])
                M = base + F[chosen[slot]]
                current = float(score[j])
                improved = True
        if not improved:
            break
    return np.sort(np.array(chosen, dtype=int)), current


def _screen(base, F, allowed, kind, weights, guard, top: int = SCREEN) -> np.ndarray:
    """Allowed candidates with the largest first-order decrease of the weighted variances.

    d var_j = -(M^-1 F M^-1)_jj: the gain is ``sum_j c_j (M^-1 F M^-1)_jj`` with
    c_j the weights (``weighted``) or, for ``worst``, (r_j / max r)^8 (the worst
    joints) plus the joints above their guard.
    """
    idx = np.flatnonzero(allowed)
    if idx.size <= top:
        return idx
    n = base.shape[-1]
    Minv = np.linalg.pinv(base + 1e-12 * np.trace(base) / n * np.eye(n))
    r = np.sqrt(np.abs(np.diag(Minv)))
    if kind == "weighted":
        c = (np.ones(n) if weights is None else np.asarray(weights, float)) / np.maximum(r, 1e-300)
    else:
        c = (r / r.max()) ** 8
        if guard is not None:
            c = c + (r > guard)
    W = Minv @ np.diag(c) @ Minv
    gain = F[idx].reshape(idx.size, -1) @ W.ravel()
    keep = np.argpartition(-gain, top - 1)[:top]
    return np.sort(idx[keep])


def random_reference(
    F: np.ndarray, group: np.ndarray, zone: np.ndarray, n: int, seed: int, designs: int = 201,
    sep: Separation | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Relative se (designs, n_joints) of seeded random zone designs, and their per-joint median."""
    zones = zones_of(zone)
    rel = np.stack([
        relative_se(F[random_design(group, zone, n, seed + 1000 + i, sep, zones)].sum(axis=0))
        for i in range(designs)
    ])
    return rel, np.median(rel, axis=0)


def choose(
    F: np.ndarray,
    group: np.ndarray,
    zone: np.ndarray,
    n: int,
    seed: int,
    kind: str = "worst",
    weights: np.ndarray | None = None,
    starts: int = 4,
    sep: Separation | None = None,
) -> np.ndarray:
    """Picks (n,) minimising the criterion: exchange from the D-optimal design and random starts.

    ``worst`` is guarded by the per-joint median relative se of random zone
    designs (:func:`random_reference`), so no joint ends up worse than the
    paper's practice. Deterministic for a given seed.
    """
    guard = (GUARD_FRACTION * random_reference(F, group, zone, n, seed, sep=sep)[1]
             if kind == "worst" else None)
    inits = [greedy_exchange(F, group, n, kind="d", sep=sep)]
    zones = zones_of(zone)
    inits += [random_design(group, zone, n, seed + 17 + i, sep, zones) for i in range(starts - 1)]
    best, best_score = inits[0], np.inf
    for init in inits:
        picks, score = exchange(F, group, init, kind, weights, guard, sep=sep)
        if score < best_score:
            best, best_score = picks, score
    return best
