"""The held-out-pose check normalised by the prediction's total uncertainty, and its limit.

A held-out pose's tests are predicted from the compliances x_h refitted without them.
The prediction error e = d - f(x_h) of its n measured components then has the
covariance ``V = Sigma + F C_h F^T``: the measurement noise Sigma (block diagonal,
per test, :func:`analysis.identification.noise.residual_covariance`) plus the
parameter uncertainty of the refit, C_h (p, p) the covariance of x_h, mapped through
the model's Jacobian F (n, p) (the held-out data are not in the refit, so the two are
independent). The statistic ``q = e^T V^-1 e`` is then chi-square with n degrees of
freedom under the noise model; it is computed from per-pose sums of the whitened
rows (W = Sigma^-1) by the Woodbury identity,
``q = e^T W e - b^T (I + C_h N)^-1 C_h b``, ``b = F^T W e``, ``N = F^T W F``, so that no
n x n matrix is formed.

Reported per pose: ``rms_normalized_total`` = sqrt(q / n) (about 1), its p-value
P(chi2_n >= q), the limit ``limit_normalized_total`` = sqrt(chi2_n^-1(1 - a) / n) and
``beyond_limit`` (q above it), with a = 1 - (1 - :data:`HOLDOUT_FAMILY_LEVEL`)^(1/P)
over the P poses validated (Sidak): data that follow the noise model flag some pose
with probability 1 %, whatever the number of poses.

Folds (:func:`holdout_folds`): poses whose joint angles are within
:data:`CLUSTER_DEG` of each other (Euclidean norm over the joints; the planner's
default minimum separation) are held out together: a pose 0.2 deg from another is
the same configuration, and each would predict the other.
"""

from __future__ import annotations

import numpy as np

from analysis.text_format import level

#: family-wise level of the held-out-pose flag (Sidak over the poses validated)
HOLDOUT_FAMILY_LEVEL = 0.01
#: poses closer than this (deg, ||dq|| over the joints) are held out together; the
#: default of the planner's ``[thresholds] min_pose_separation_deg``
CLUSTER_DEG = 5.0
#: above this many poses the folds are the poses: a neighbour is one of more than this
#: many poses in the refit, too small a share of its information to make the check
#: optimistic (and the search would cost ~40 MB at 1e5 poses)
CLUSTER_MAX_POSES = 20_000
#: up to this many poses the close pairs come from the full (G, G) distance matrix (its
#: (G, G, 6) differences: 3 MB at 256 poses); above, from scipy's k-d tree, whose import
#: (scipy.spatial, with scipy.sparse) costs more CPU than a planned campaign's search
DENSE_PAIRS_MAX_POSES = 256
LIMIT_TEXT = (
    "a held-out pose is flagged (beyond_limit) when q = e^T (Sigma + F C F^T)^-1 e of its n "
    "measured components exceeds the chi-square(n) quantile at 1 - a, a = 1 - (1 - "
    f"{HOLDOUT_FAMILY_LEVEL:g})^(1/P) over the P poses (Sidak, {level(HOLDOUT_FAMILY_LEVEL)} "
    "family-wise); limit_normalized_total = sqrt(quantile / n)")


class PredictiveSums:
    """Per-pose sums of whitened held-out rows: ``eWe`` (P,), ``FWe`` (P, p), ``FWF``
    (upper triangles, P x p (p + 1) / 2, float32: a diagnostic's p x p matrix, 8 MB
    instead of 17 at 1e5 poses), ``n`` (P,) measured components; ``add`` a block of
    tests at a time. ``normal``: a callable giving N = F^T W F of poses h when the
    caller has it (then ``FWF`` is not summed)."""

    def __init__(self, n_folds: int, p: int, normal=None, parameter: bool = True) -> None:
        self.P, self.p = n_folds, p
        self.iu = np.triu_indices(p)
        self.eWe, self.n = np.zeros(n_folds), np.zeros(n_folds)
        #: without the refit's parameter term (:data:`PARAMETER_TERM_MAX_POSES`) only
        #: e^T W e and n are summed
        self.parameter = parameter
        self.FWe = np.zeros((n_folds, p)) if parameter else None
        self._normal = normal
        self.FWF = None if normal is not None or not parameter else np.zeros(
            (n_folds, len(self.iu[0])), dtype=np.float32)

    def add(self, fold: np.ndarray, Linv: np.ndarray, F: np.ndarray, err: np.ndarray,
            measured: np.ndarray) -> None:
        """fold (b,) ints; Linv (b, 6, 6) whitening (rows of unmeasured components zero);
        F (b, 6, p) model Jacobian (m/(rad/(N m)), ...); err (b, 6) prediction errors
        (m, rad; ignored where not measured)."""
        P = self.P
        Le = np.einsum("mij,mj->mi", Linv, np.where(measured, err, 0.0))
        LF = Linv @ np.where(measured[..., None], F, 0.0) if self.parameter else None
        self.eWe += np.bincount(fold, np.sum(Le ** 2, axis=1), P)
        self.n += np.bincount(fold, measured.sum(axis=1), P)
        if not self.parameter:
            return
        Fe = np.einsum("mri,mr->mi", LF, Le)
        for a in range(Fe.shape[1]):
            self.FWe[:, a] += np.bincount(fold, Fe[:, a], P)
        if self.FWF is None:
            return
        FF = np.einsum("mri,mrj->mij", LF, LF)[:, self.iu[0], self.iu[1]]
        for a in range(FF.shape[1]):
            self.FWF[:, a] += np.bincount(fold, FF[:, a], P)

    def normal(self, h: np.ndarray) -> np.ndarray:
        """N = F^T W F (len(h), p, p) of poses h."""
        if self._normal is not None:
            return self._normal(h)
        out = np.empty((len(h), self.p, self.p))
        out[:, self.iu[0], self.iu[1]] = self.FWF[h]
        out[:, self.iu[1], self.iu[0]] = self.FWF[h]
        return out


#: poses per chunk of the per-pose p x p algebra
CHUNK = 8192
#: above this many folds the refit's parameter term F C_h F^T is left out of V: a fold's
#: refit rests on all the other poses, so the term shrinks as 1/P (measured, OLS at w_eff:
#: sqrt(q/n) +22 % at 60 poses, +1.6 % at most at 1000, on the side of flagging), and q
#: is then e^T Sigma^-1 e (no per-fold p x p sums: 40 MB at 1e5 poses)
PARAMETER_TERM_MAX_POSES = 1000


def predictive_statistic(sums: PredictiveSums, covariance) -> np.ndarray:
    """q (P,) = e^T (Sigma + F C_h F^T)^-1 e per pose. ``covariance(h)``: the covariances
    C_h (len(h), p, p) of the refits of poses h ((rad/(N m))^2), made in chunks of poses;
    NaN where C_h is not finite."""
    p = sums.p
    if not sums.parameter:  # the noise term alone
        return sums.eWe.copy()
    out = np.full(sums.P, np.nan)
    for s in range(0, sums.P, CHUNK):
        h = np.arange(s, min(s + CHUNK, sums.P))
        C = covariance(h)
        ok = np.all(np.isfinite(C.reshape(len(h), -1)), axis=1)
        if not ok.any():
            continue
        C, hk = C[ok], h[ok]
        Cb = C @ sums.FWe[hk][..., None]  # C b
        K = np.eye(p) + C @ sums.normal(hk)  # I + C N
        y = np.linalg.solve(K, Cb)[..., 0]
        out[hk] = np.maximum(sums.eWe[hk] - np.einsum("fi,fi->f", sums.FWe[hk], y), 0.0)
    return out


def flag_columns(q: np.ndarray, n: np.ndarray, level: float = HOLDOUT_FAMILY_LEVEL) -> dict:
    """The table's columns from q (P,) and the measured components n (P,) of each pose:
    ``rms_normalized_total``, ``p_value_total``, ``limit_normalized_total`` and
    ``beyond_limit`` (see the module docstring)."""
    from scipy import special  # chi-square tails without importing scipy.stats

    q, n = np.asarray(q, float), np.asarray(n, float)
    valid = np.isfinite(q) & (n > 0)
    P = max(int(valid.sum()), 1)
    per_pose = -np.expm1(np.log1p(-level) / P)  # 1 - (1 - level)^(1/P)
    nn = np.where(n > 0, n, 1.0)
    with np.errstate(invalid="ignore"):
        p_value = np.where(valid, special.chdtrc(nn, np.where(valid, q, 0.0)), np.nan)
        limit = np.where(n > 0, np.sqrt(special.chdtri(nn, per_pose) / nn), np.nan)
        rms = np.where(valid, np.sqrt(np.where(valid, q, 0.0) / nn), np.nan)
    return {"rms_normalized_total": rms, "p_value_total": p_value,
            "limit_normalized_total": limit,
            "beyond_limit": valid & (p_value < per_pose)}


def close_pairs(points: np.ndarray, radius: float) -> np.ndarray:
    """Pairs (k, 2) of row indices i < j of ``points`` (G, n) with
    ||points_i - points_j|| <= ``radius`` (Euclidean, the points' unit), in any order.

    Up to :data:`DENSE_PAIRS_MAX_POSES` points from the distance matrix, else from
    scipy's ``cKDTree.query_pairs``: the same pairs either way."""
    if len(points) > DENSE_PAIRS_MAX_POSES:
        from scipy.spatial import cKDTree

        return cKDTree(points).query_pairs(radius, output_type="ndarray")
    d2 = np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=-1)  # (G, G)
    i, j = np.nonzero(np.triu(d2 <= radius * radius, k=1))
    return np.column_stack([i, j])


def holdout_folds(q: np.ndarray, group: np.ndarray, radius: float) -> np.ndarray:
    """Fold (m,) of each test: its pose ``group`` (m,) ints, with the poses whose joint
    angles are within ``radius`` (rad, Euclidean norm over the joints of q (m, n) rad)
    of a fold's first pose held out with it; folds numbered by first appearance.

    Leader clustering, not single linkage: each pose not yet in a fold, in order of first
    appearance, opens a fold with every unassigned pose within ``radius`` of it, so a
    chain of poses each close to the next does not merge a whole dense campaign (a
    fold's poses are within 2 ``radius`` of each other). ``radius`` 0, or more than
    :data:`CLUSTER_MAX_POSES` poses: ``group`` itself (not a copy).
    """
    group = np.asarray(group)
    n_groups = int(group.max(initial=-1)) + 1
    if radius <= 0 or n_groups < 2 or n_groups > CLUSTER_MAX_POSES:
        return group  # the poses themselves (no copy: 8 MB at 1e6 tests)
    _, first = np.unique(group, return_index=True)  # groups are 0..G-1 by first appearance
    rep = np.asarray(q, dtype=float)[first]  # (G, n) a reading of each pose
    # only the close pairs (i < j), as one array: few in a planned campaign
    pairs = close_pairs(rep, radius * (1 + 1e-12))
    fold_of = np.full(n_groups, -1)
    if len(pairs):
        # each pose's later neighbours, by the pair list sorted on its first member
        pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
        start = np.searchsorted(pairs[:, 0], np.arange(n_groups + 1))
        n_folds = 0
        for g in np.unique(pairs.ravel()):  # the poses with a neighbour, in order
            if fold_of[g] >= 0:
                continue
            members = pairs[start[g]:start[g + 1], 1]
            fold_of[g] = n_folds
            fold_of[members[fold_of[members] < 0]] = n_folds
            n_folds += 1
    # every other pose is a fold of its own; folds renumbered by first appearance
    alone = fold_of < 0
    fold_of[alone] = fold_of.max(initial=-1) + 1 + np.arange(int(alone.sum()))
    _, renumber = np.unique(fold_of, return_index=True)
    rank = np.empty(len(renumber), dtype=int)
    rank[np.argsort(renumber, kind="stable")] = np.arange(len(renumber))
    return rank[fold_of][group]
