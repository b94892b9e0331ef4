"""Which tests share a pose: joint angles equal to within the encoder noise.

Rounded angles are not a test of equality: two readings of one pose that
straddle a rounding boundary count as two poses, and with encoder jitter every
reading is "distinct". Two tests are at the same pose when every joint angle
agrees to within :func:`pose_tolerance` (a multiple of the encoder's sigma);
poses are the connected groups of that relation (single linkage), so a chain
of jittered readings of one pose stays one pose. The ``pose`` labels name the
groups; they do not decide them (one pose may carry several labels, e.g. one
per load case).
"""

from __future__ import annotations

import numpy as np

from analysis.identification.noise import NoiseModel

#: tolerance in encoder sigmas: jitter stays far inside it (a normal reading is within
#: 4 sigma with probability 1 - 6e-5, a difference of two within 5.7 sigma), while poses
#: of a campaign differ by degrees (a degree is ~6000 sigma of a 0.001 deg encoder)
POSE_TOLERANCE_SIGMAS = 20.0


def pose_tolerance(noise: NoiseModel | None = None) -> float:
    """Largest joint-angle difference (rad) between two readings of one pose."""
    return POSE_TOLERANCE_SIGMAS * (noise or NoiseModel()).joint_sigma


def pose_groups(q: np.ndarray, tol: float) -> np.ndarray:
    """Pose index (m,) of each test: 0, 1, ... in order of first appearance.

    q : (m, n) joint angles (rad). Tests i, j are linked when
    max_k |q_ik - q_jk| <= tol; a pose is a connected group of links.

    Computed without comparing every pair (memory and time ~ m log m for
    campaign data): a gap wider than ``tol`` between consecutive sorted values
    of one joint separates the tests on either side for good (no link crosses
    it), so the tests are split at such gaps, joint after joint, until no split
    is left. A part whose extent is within ``tol`` in every joint is one pose
    (all its pairs are linked). Any other part (e.g. a drift of readings longer
    than ``tol``) is resolved exactly by a sweep along its widest joint that
    links the pairs within ``tol`` of each other (:func:`_components_by_sweep`).
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[0] == 0:
        return np.zeros(0, dtype=int)
    return _pose_groups(q, tol)


def _pose_groups(q: np.ndarray, tol: float) -> np.ndarray:
    part = _split_at_gaps(q, tol)
    lo = np.full((part.max() + 1, q.shape[1]), np.inf)
    hi = np.full_like(lo, -np.inf)
    np.minimum.at(lo, part, q)
    np.maximum.at(hi, part, q)
    wide = np.flatnonzero(np.any(hi - lo > tol, axis=1))
    if wide.size:
        label = part.copy()
        next_label = part.max() + 1
        order = np.argsort(part, kind="stable")
        bounds = np.searchsorted(part[order], np.stack([wide, wide + 1]))
        for p, a, b in zip(wide, bounds[0], bounds[1], strict=True):
            rows = order[a:b]
            sub = _components_by_sweep(q[rows], tol, int(np.argmax(hi[p] - lo[p])))
            label[rows] = next_label + sub
            next_label += sub.max() + 1
        part = label
    # number the groups by first appearance
    _, first, inverse = np.unique(part, return_index=True, return_inverse=True)
    rank = np.empty(first.size, dtype=int)
    rank[np.argsort(first, kind="stable")] = np.arange(first.size)
    return rank[inverse.reshape(-1)]


def _split_at_gaps(q: np.ndarray, tol: float) -> np.ndarray:
    """(m,) part index: tests split at every gap > tol of a joint, until stable."""
    m, n = q.shape
    part = np.zeros(m, dtype=np.int64)
    count, stable = 1, 0
    k = 0
    while stable < n:  # a full round over the joints without a new split
        order = np.lexsort((q[:, k], part))
        qs, ps = q[order, k], part[order]
        new = (np.diff(ps) != 0) | (np.diff(qs) > tol)
        relabel = np.empty(m, dtype=np.int64)
        relabel[order] = np.concatenate([[0], np.cumsum(new)])
        new_count = int(relabel.max()) + 1
        stable = stable + 1 if new_count == count else 1
        part, count = relabel, new_count
        k = (k + 1) % n
    return part


def _components_by_sweep(q: np.ndarray, tol: float, axis: int) -> np.ndarray:
    """Exact connected components (0-based labels) of the tolerance links among q (g, n).

    Sorted along ``axis``, a linked pair is at most ``tol`` apart there, so
    each test is compared only with the following tests within that window.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = q.shape[0]
    order = np.argsort(q[:, axis], kind="stable")
    qs = q[order]
    rows, cols = [], []
    for s in range(1, g):
        near = qs[s:, axis] - qs[:-s, axis] <= tol
        if not near.any():
            break
        i = np.flatnonzero(near)
        link = np.max(np.abs(qs[i + s] - qs[i]), axis=1) <= tol
        rows.append(i[link])
        cols.append(i[link] + s)
    r = np.concatenate(rows) if rows else np.zeros(0, dtype=int)
    c = np.concatenate(cols) if cols else np.zeros(0, dtype=int)
    graph = coo_matrix((np.ones(r.size, dtype=np.int8), (r, c)), shape=(g, g))
    _, sorted_label = connected_components(graph, directed=False)
    label = np.empty(g, dtype=int)
    label[order] = sorted_label
    return label


def pose_groups_pairwise(q: np.ndarray, tol: float) -> np.ndarray:
    """Reference for :func:`pose_groups`: compares every pair (m x m memory; small m only)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    m = q.shape[0]
    close = np.max(np.abs(q[:, None, :] - q[None, :, :]), axis=-1) <= tol
    group = np.full(m, -1)
    count = 0
    for start in range(m):
        if group[start] >= 0:
            continue
        group[start] = count
        stack = [start]
        while stack:
            i = stack.pop()
            new = np.flatnonzero(close[i] & (group < 0))
            group[new] = count
            stack.extend(new.tolist())
        count += 1
    return group


def count_poses(q: np.ndarray, tol: float) -> int:
    """Number of distinct poses among the tests (see :func:`pose_groups`)."""
    return int(pose_groups(q, tol).max(initial=-1) + 1)


def factorize_labels(labels, block: int = 1 << 16) -> tuple[np.ndarray, list[str]]:
    """(codes (m,) int64, uniques): the labels' text numbered in order of first appearance.

    Factorized a block at a time (the hash table of one call over 1e6 labels is sized for
    1e6 entries, ~50 MB; a block's is sized for the block), each block's distinct labels
    then numbered by their text, so labels equal only as text share a code.
    """
    import pandas as pd

    labels = np.asarray(labels, dtype=object)
    codes = np.empty(labels.shape[0], dtype=np.int64)
    number: dict[str, int] = {}
    for s in range(0, labels.shape[0], block):
        local, uniques = pd.factorize(labels[s:s + block], use_na_sentinel=False)
        glob = np.array([number.setdefault(str(u), len(number)) for u in uniques],
                        dtype=np.int64)
        codes[s:s + block] = glob[local]
    return codes, list(number)


def group_names(labels: np.ndarray, group: np.ndarray) -> list[str]:
    """Name of each pose group: its labels joined with '+', in order of appearance."""
    codes, uniques = factorize_labels(labels)
    n_groups = int(group.max(initial=-1)) + 1
    # first appearance of each (group, label) pair, then the pairs by group and appearance
    pair = group.astype(np.int64) * max(len(uniques), 1) + codes
    _, first = np.unique(pair, return_index=True)
    first = np.sort(first)
    names: list[list[str]] = [[] for _ in range(n_groups)]
    for i in first:
        names[group[i]].append(str(uniques[codes[i]]))
    return ["+".join(n) for n in names]
