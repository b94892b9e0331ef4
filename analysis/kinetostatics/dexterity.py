"""Dexterity: normalized Jacobian, Frobenius condition number (Dumas et al. 2011, eqs. 3-4)
and the characteristic length."""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.small_linalg import inverse_frobenius2, to_entry_major
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


def normalized_jacobian(J: np.ndarray, length: float) -> np.ndarray:
    """J_N = diag(I/L, I) J (eq. 4): translational rows divided by L (m); dimensionless."""
    scale = np.array([1.0 / length] * 3 + [1.0] * 3)
    return J * scale[:, None]


def frobenius_condition(M: np.ndarray) -> np.ndarray:
    """kappa_F(M) = (1/m) sqrt(tr(M^T M) tr((M^T M)^-1)) (eq. 3), batched over (..., m, m).

    Returns ``inf`` where M is singular (rank-deficient to working precision),
    never NaN.
    """
    M = np.asarray(M, dtype=float)
    m = M.shape[-1]
    kappa = frobenius_condition_em(to_entry_major(M.reshape(-1, m, m)))
    return kappa.reshape(M.shape[:-2])


def frobenius_condition_em(M: np.ndarray) -> np.ndarray:
    """kappa_F (N,) of entry-major matrices M (m, m, N); the kernel of frobenius_condition."""
    m = M.shape[0]
    # tr((M^T M)^-1) = ||M^-1||_F^2 from a batched QR: no explicit inverse, no LAPACK
    # call per matrix.
    inv_norm2 = inverse_frobenius2(M)
    bad = ~np.isfinite(inv_norm2)
    if np.any(bad):
        # Some matrix is exactly singular: singular values never fail.
        s = np.linalg.svd(np.moveaxis(M[:, :, bad], -1, 0), compute_uv=False)
        singular = s[..., -1] <= s[..., 0] * 1e-15
        safe = np.where(singular[..., None], 1.0, s)
        inv_norm2[bad] = np.where(singular, np.inf, np.sum(1.0 / safe**2, axis=-1))
    with np.errstate(over="ignore", invalid="ignore"):
        kappa = np.sqrt(np.einsum("ijn,ijn->n", M, M) * inv_norm2) / m
    # Beyond 1e15 the matrix is singular to working precision.
    return np.where(kappa > 1e15, np.inf, kappa)


def inverse_condition(M: np.ndarray) -> np.ndarray:
    """1/kappa_F in [0, 1]; exactly 0 at a singular pose."""
    kappa = frobenius_condition(M)
    return np.where(np.isinf(kappa), 0.0, 1.0 / kappa)


def inverse_condition_em(M: np.ndarray) -> np.ndarray:
    """1/kappa_F (N,) of entry-major matrices M (m, m, N); exactly 0 where singular."""
    kappa = frobenius_condition_em(M)
    return np.where(np.isinf(kappa), 0.0, 1.0 / kappa)


def characteristic_length(
    robot: RobotModel, starts: int = 6, seed: int = 0, samples: int = 20000
) -> tuple[float, np.ndarray, float]:
    """Characteristic length L (m) minimising the condition number of J_N.

    Method (Khan and Angeles 2006, the paper's ref. [22]): L and the posture
    are chosen together to minimise kappa_F(J_N(q, L)); q_1 does not affect
    kappa_F and is held at 0. The problem is not convex: a batched search over
    ``samples`` seeded random postures (within the limits; a joint with more
    than a full turn within -pi..pi) and a logarithmic grid of L picks the
    ``starts`` best pairs from distinct basins, each then refined by a bounded
    Nelder-Mead search over (q_2..q_n, log L). For the KR240-2 this returns
    L = 0.70 m (kappa_F = 1.285 near theta = 0, 29, -220, 0, -101 deg); the
    paper gives 0.682 m. The search is a good answer, not a proof of the global
    one.

    Returns
    -------
    (L, q_opt, kappa_min) : L in m, the optimal posture (rad), the minimum kappa_F.
    """
    from scipy.optimize import minimize  # heavy: only this search needs it

    rng = np.random.default_rng(seed)
    reach = np.linalg.norm(robot.chain.placements[:, :3, 3], axis=1).sum() + np.linalg.norm(
        robot.chain.tip[:3, 3]
    )
    lo, hi = (v[1:] for v in robot.map_limits())
    log_bounds = (np.log(reach / 100), np.log(reach * 10))

    # Coarse batched search.
    q = np.zeros((samples, robot.n))
    q[:, 1:] = rng.uniform(lo, hi, size=(samples, robot.n - 1))
    J = jacobian(robot, q)
    lengths = np.geomspace(reach / 20, reach, 16)
    kappa = np.stack([frobenius_condition(normalized_jacobian(J, L)) for L in lengths], axis=1)
    # Best (posture, L) pairs from distinct basins: a pick must differ from every
    # earlier pick by more than 20 deg in some joint of q2..q5 (q6 rarely matters).
    flat = np.argsort(kappa, axis=None)
    picks: list[tuple[int, int]] = []
    for idx in flat:
        i, j = divmod(int(idx), lengths.size)
        far = all(np.max(np.abs(q[i, 1:5] - q[k, 1:5])) > np.radians(20) for k, _ in picks)
        if far:
            picks.append((i, j))
        if len(picks) == starts:
            break

    def cost(z: np.ndarray) -> float:
        qz = np.concatenate([[0.0], z[:-1]])
        k = frobenius_condition(normalized_jacobian(jacobian(robot, qz), np.exp(z[-1])))
        return float(k) if np.isfinite(k) else 1e12

    bounds = [*zip(lo, hi, strict=True), log_bounds]
    best = None
    for i, j in picks:
        z0 = np.concatenate([q[i, 1:], [np.log(lengths[j])]])
        res = minimize(cost, z0, method="Nelder-Mead", bounds=bounds,
                       options={"maxiter": 3000, "xatol": 1e-7, "fatol": 1e-10})
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    q_opt = np.concatenate([[0.0], best.x[:-1]])
    return float(np.exp(best.x[-1])), q_opt, float(best.fun)
