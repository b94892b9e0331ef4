"""Optimal experimental design for the linear model of Dumas et al. (2011), pure numpy.

For a test (pose, wrench) the deflection is ``delta_d = A x`` (eqs. 16-18),
``x = 1/k`` (rad/(N m)). Each row of A is divided by the standard deviation of
the measured component (m for translations, rad for rotations) and each column
multiplied by the prior compliance ``x0 = 1/k0``, so that the information
matrix ``M = sum B_i^T B_i`` is that of the *relative* compliances
``x / x0``. Its inverse is the covariance of the relative compliances, equal
to that of the relative stiffnesses to first order (delta method: the standard
error of k is ``se_k = k^2 se_x``, so ``se_k / k = se_x / x``).
"""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.linear_model import design_block
from campaign.planning.separation import Separation, blocked


def scaled_blocks(
    J: np.ndarray, wrenches: np.ndarray, sigma: np.ndarray, k_prior: np.ndarray
) -> np.ndarray:
    """Weighted, column-scaled design blocks B (..., 6, n) (dimensionless).

    Parameters
    ----------
    J : (..., 6, n) Jacobians (m/rad, rad/rad).
    wrenches : (..., 6) wrenches [N; N m], base frame.
    sigma : (6,) standard deviation of each measured component [m x3; rad x3].
    k_prior : (n,) prior joint stiffness (N m/rad).
    """
    A = design_block(J, wrenches)
    return A / sigma[:, None] / k_prior


def information(B: np.ndarray) -> np.ndarray:
    """Information matrices F = B^T B (..., n, n) of blocks B (..., rows, n)."""
    return np.einsum("...ri,...rj->...ij", B, B)


def information_of_tests(
    J: np.ndarray, W: np.ndarray, sigma: np.ndarray, k_prior: np.ndarray, block: int = 4096
) -> np.ndarray:
    """Information F (T, n, n) of T tests, each one pose J (T, 6, n) under c wrenches W (T, c, 6).

    Equal to ``sum_c information(scaled_blocks(J, W[:, c], sigma, k_prior))``, computed
    without the blocks: with ``t = J^T w / k0`` the block is ``diag(1/sigma) J diag(t)``, so
    ``F = G o (t t^T)`` with ``G = J^T diag(sigma^-2) J`` the same for every load case
    (o: element-wise product). Runs in blocks of poses with BLAS on one thread (3x3 and
    6x6 products on huge batches otherwise hit BLAS threading).
    """
    from threadpoolctl import threadpool_limits

    T, n = J.shape[0], J.shape[-1]
    F = np.empty((T, n, n))
    s2 = 1.0 / np.asarray(sigma, dtype=float) ** 2
    with threadpool_limits(limits=1):
        for lo in range(0, T, block):
            Jb, Wb = J[lo:lo + block], W[lo:lo + block]
            G = np.einsum("tri,r,trj->tij", Jb, s2, Jb, optimize=True)
            t = np.einsum("tri,tcr->tci", Jb, Wb) / k_prior
            F[lo:lo + block] = G * np.einsum("tci,tcj->tij", t, t)
    return F


def predicted_se(M: np.ndarray, k_prior: np.ndarray) -> np.ndarray:
    """Standard error of each identified k (N m/rad) for information M (n, n) of relative x.

    ``cov(x/x0) = M^-1``, ``se_k = k^2 se_x = k * sqrt(diag(M^-1))``. Returns inf
    where M is singular (some k not identifiable).
    """
    try:
        cov = np.linalg.inv(M)
    except np.linalg.LinAlgError:
        return np.full(len(k_prior), np.inf)
    d = np.diag(cov)
    if np.any(~np.isfinite(d)) or np.any(d <= 0) or np.linalg.cond(M) > 1e14:
        return np.full(len(k_prior), np.inf)
    return k_prior * np.sqrt(d)


def criterion(M: np.ndarray, kind: str) -> np.ndarray:
    """Design criterion of information matrices M (..., n, n), larger is better.

    ``d``: log det M (-inf if singular); ``e``: smallest eigenvalue of M.
    """
    if kind == "d":
        sign, logdet = np.linalg.slogdet(M)
        return np.where(sign > 0, logdet, -np.inf)
    if kind == "e":
        return np.linalg.eigvalsh(M)[..., 0]
    raise ValueError(f"unknown criterion {kind!r}")


def _ridge(F: np.ndarray) -> np.ndarray:
    """A tiny multiple of the identity that makes the greedy start well posed."""
    scale = float(np.mean(np.trace(F, axis1=-2, axis2=-1))) / F.shape[-1]
    return 1e-9 * max(scale, 1e-300) * np.eye(F.shape[-1])


#: candidates evaluated exactly at each step; the rest are screened out by a
#: first-order score (see :func:`_best`)
SCREEN = 512


def _top(score: np.ndarray, k: int) -> np.ndarray:
    """Indices of the k largest scores (ties: lowest index), unsorted."""
    part = np.argpartition(-score, k - 1)[:k]
    cut = score[part].min()
    above = np.flatnonzero(score > cut)
    ties = np.flatnonzero(score == cut)[: k - above.size]
    return np.concatenate([above, ties])


def _best(base: np.ndarray, F: np.ndarray, allowed: np.ndarray, kind: str,
          top: int = SCREEN) -> tuple[int, float]:
    """Index and criterion of the best ``base + F[j]`` over allowed j.

    When more than ``top`` candidates are allowed, only ``top`` of them are
    evaluated exactly: those with the largest first-order D gain
    ``tr(base^-1 F_j)``; for E, half of them and half with the largest
    ``v^T F_j v`` along the weakest eigenvector v of base.
    """
    idx = np.flatnonzero(allowed)
    if idx.size == 0:
        return -1, -np.inf
    if idx.size > top:
        flat = F.reshape(F.shape[0], -1)
        gain = np.where(allowed, flat @ np.linalg.inv(base).T.ravel(), -np.inf)
        keep = _top(gain, top if kind == "d" else top // 2)
        if kind == "e":
            v = np.linalg.eigh(base)[1][:, 0]
            weak = np.where(allowed, flat @ np.outer(v, v).ravel(), -np.inf)
            keep = np.union1d(keep, _top(weak, top // 2))
        idx = np.sort(keep)
    score = criterion(base + F[idx], kind)
    j = int(np.argmax(score))
    return int(idx[j]), float(score[j])


def greedy_exchange(
    F: np.ndarray,
    group: np.ndarray,
    n: int,
    kind: str = "d",
    max_passes: int = 20,
    rel_tol: float = 1e-6,
    sep: Separation | None = None,
) -> np.ndarray:
    """Choose n candidates maximising the criterion of the summed information.

    Greedy forward selection, then Fedorov-type exchange passes (swap a chosen
    candidate for the best unchosen one while the criterion improves). Each
    step evaluates exactly the :data:`SCREEN` candidates with the best
    first-order gain (all of them when there are fewer).

    Parameters
    ----------
    F : (N, p, p) information matrix of each candidate test.
    group : (N,) integer group of each candidate (a pose); at most one
        candidate per group is chosen (a pose is tested once).
    n : number of candidates to choose.
    kind : ``"d"`` (D-optimal, log det) or ``"e"`` (E-optimal, smallest eigenvalue).
    max_passes, rel_tol : exchange passes stop after ``max_passes`` or when no swap
        improves the criterion by more than ``rel_tol`` (relative).
    sep : also keep the chosen poses apart by its minimum joint-space separation
        (:mod:`campaign.planning.separation`); raises ValueError when the candidates run out.

    Returns
    -------
    (n,) indices of the chosen candidates, sorted ascending. Deterministic:
    ties are broken by the lowest index.
    """
    if n > len(np.unique(group)):
        raise ValueError(f"cannot choose {n} tests from {len(np.unique(group))} poses")
    chosen: list[int] = []
    M = _ridge(F)
    free = np.ones(F.shape[0], dtype=bool)
    for _ in range(n):
        best, _score = _best(M, F, free, kind)
        if best < 0:
            raise ValueError(f"cannot choose {n} poses this far apart from the candidates")
        chosen.append(best)
        M = M + F[best]
        free &= ~blocked(group, [best], sep)
    current = float(criterion(M, kind))
    # what each chosen candidate blocks, and how many chosen block each candidate: a slot's
    # allowed set is then O(N) (the others' union without recomputing their distances)
    masks = [blocked(group, [c], sep) for c in chosen]
    count = np.sum(masks, axis=0, dtype=np.int64)
    for _ in range(max_passes):
        improved = False
        for slot in range(n):
            base = M - F[chosen[slot]]
            allowed = (count - masks[slot]) == 0
            best, score = _best(base, F, allowed, kind)
            if score > current + rel_tol * max(1.0, abs(current)):
                chosen[slot] = best
                M = base + F[best]
                current = score
                improved = True
                count -= masks[slot]
                masks[slot] = blocked(group, [best], sep)
                count += masks[slot]
        if not improved:
            break
    return np.sort(np.array(chosen, dtype=int))


def zones_of(zone: np.ndarray) -> np.ndarray:
    """The distinct zone indices of ``zone`` (N,), sorted (= ``np.unique``, cheaper for ints)."""
    zone = np.asarray(zone)
    if zone.dtype.kind in "iu" and zone.size and zone.min() >= 0:
        return np.flatnonzero(np.bincount(zone))  # = np.unique(zone), without its hashing
    return np.unique(zone)


def random_design(group: np.ndarray, zone: np.ndarray, n: int, seed: int,
                  sep: Separation | None = None, zones: np.ndarray | None = None) -> np.ndarray:
    """The paper's practice: n distinct poses drawn at random, cycling through the zones.

    Parameters
    ----------
    group : (N,) pose of each candidate; zone : (N,) zone index of each candidate.
    sep : also keep the poses apart by its minimum separation (:mod:`campaign.planning.separation`).
    zones : ``zones_of(zone)`` when the caller draws many designs from the same candidates
        (its count over 4e5 candidates costs more than the design).
    Returns (n,) sorted candidate indices (one candidate per pose, chosen at random).

    Each pick is uniform over the zone's candidates whose pose is not used yet. It is
    drawn by rejection from all N candidates (a batch of :data:`_DRAWS` at a time), so a
    design costs O(n) instead of a scan of the N candidates per pick (the planner draws
    ~200 of them against 1e5 candidates); a scan decides only when no draw lands.
    """
    rng = np.random.default_rng(seed)
    group, zone = np.asarray(group), np.asarray(zone)
    zones = zones_of(zone) if zones is None else zones
    picked: list[int] = []
    used: set[int] = set()
    order = rng.permutation(zones)
    i = 0
    stalled = 0
    while len(picked) < n and stalled < len(zones):
        z = order[i % len(order)]
        i += 1
        draws = rng.integers(0, len(zone), _DRAWS)
        hits = draws[zone[draws] == z]
        pick = next((int(j) for j in hits if int(group[j]) not in used
                     and (sep is None or not sep.conflicts(int(j), picked))), None)
        if pick is None:  # none of the draws landed: scan (rare, or the zone is used up)
            free = ~np.isin(group, list(used))
            if sep is not None and picked:
                free &= ~sep.blocked(picked)
            idx = np.flatnonzero((zone == z) & free)
            if idx.size == 0:
                stalled += 1
                continue
            pick = int(rng.choice(idx))
        stalled = 0
        picked.append(pick)
        used.add(int(group[pick]))
    if len(picked) < n:
        raise ValueError(f"cannot choose {n} distinct poses from the candidates")
    return np.sort(np.array(picked, dtype=int))


#: candidates drawn at once per pick of :func:`random_design` (a zone holding a quarter
#: of the candidates is missed by all of them with probability 0.75^64 ~ 1e-8)
_DRAWS = 64
