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
    """
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


def group_names(labels: np.ndarray, group: np.ndarray) -> list[str]:
    """Name of each pose group: its labels joined with '+', in order of appearance."""
    names = []
    for g in range(int(group.max(initial=-1)) + 1):
        names.append("+".join(dict.fromkeys(str(s) for s in labels[group == g])))
    return names
