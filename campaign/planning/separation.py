"""Minimum joint-space separation between the distinct poses of a design.

Two tests whose joint angles differ by a fraction of a degree are, for the model
(J, K_C), the same configuration: a design holding both has one pose fewer than
it says, and its held-out check is optimistic (each predicts the other). The
planner therefore never chooses two poses closer than ``[thresholds]
min_pose_separation_deg`` (default :data:`DEFAULT_MIN_SEPARATION_DEG`), measured as
the Euclidean norm of the joint-angle difference over all joints. At 5 deg the
Jacobian's columns turn by about 9 % (sin 5 deg) of their length: distinct
enough to count as another configuration, small against the zones' extent
(tens of degrees per joint), so the criteria lose little.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from analysis.identification.validation.holdout_check import CLUSTER_DEG

#: default of the protocol key ``[thresholds] min_pose_separation_deg``: the distance
#: below which the held-out validation holds poses out together
DEFAULT_MIN_SEPARATION_DEG = CLUSTER_DEG


class Separation:
    """Which candidate tests a design may not add next to the ones it holds.

    ``q`` (N, n): joint angles of each candidate test (rad); ``group`` (N,): its pose
    (candidates of one pose share it: a pose is tested once); ``min_rad``: the
    smallest allowed distance ||q_i - q_j|| between two distinct poses (rad).
    """

    def __init__(self, q: np.ndarray, group: np.ndarray, min_rad: float) -> None:
        self.q = np.asarray(q, dtype=float)
        self.group = np.asarray(group)
        self.min2 = float(min_rad) ** 2
        # joint-major copy: a distance to every candidate is then a few passes over
        # contiguous (N,) vectors instead of a reduction over rows of length n
        self._q_by_joint = np.ascontiguousarray(self.q.T)

    def blocked(self, chosen: Sequence[int]) -> np.ndarray:
        """(N,) bool: candidates of a chosen pose or closer than the minimum to one."""
        chosen = np.asarray(chosen, dtype=int).reshape(-1)
        out = np.isin(self.group, self.group[chosen])
        if self.min2 > 0:
            for c in chosen:  # a few chosen poses against every candidate: O(N n) each
                out |= self._distance2(c) < self.min2
        return out

    def _distance2(self, c: int) -> np.ndarray:
        """(N,) ||q_i - q_c||^2 (rad^2), summed over the joints in order (as ``np.sum``)."""
        d2 = np.empty(self._q_by_joint.shape[1])
        tmp = np.empty_like(d2)
        for j, qj in enumerate(self._q_by_joint):
            np.subtract(qj, qj[c], out=tmp)
            np.multiply(tmp, tmp, out=tmp)
            if j == 0:
                d2[:] = tmp
            else:
                d2 += tmp
        return d2

    def conflicts(self, j: int, chosen: Sequence[int]) -> bool:
        """Candidate ``j`` shares a pose with, or is too close to, one of ``chosen``."""
        chosen = np.asarray(chosen, dtype=int).reshape(-1)
        if not chosen.size:
            return False
        if np.any(self.group[chosen] == self.group[j]):
            return True
        return bool(np.any(np.sum((self.q[chosen] - self.q[j]) ** 2, axis=1) < self.min2))


def blocked(group: np.ndarray, chosen: Sequence[int], sep: Separation | None) -> np.ndarray:
    """(N,) bool: candidates a design holding ``chosen`` may not add (their pose, and with
    ``sep`` those too close to one)."""
    if sep is not None:
        return sep.blocked(chosen)
    return np.isin(group, np.asarray(group)[np.asarray(chosen, dtype=int)])


def min_pairwise_distance(q: np.ndarray) -> float:
    """Smallest ||q_i - q_j|| over distinct rows of q (m, n) (the units of q); inf for m < 2."""
    q = np.asarray(q, dtype=float)
    if len(q) < 2:
        return float("inf")
    d = np.sqrt(np.sum((q[:, None, :] - q[None, :, :]) ** 2, axis=-1))
    return float(np.min(d[np.triu_indices(len(q), 1)]))
