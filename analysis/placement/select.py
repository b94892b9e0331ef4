"""The free tool angle at each path point, chosen by dynamic programming.

Along the path, the angle index a_n at point n is chosen to minimise the
objective (the largest per-point cost for ``max`` and ``compliance``, the sum of
squares for ``rms``) over all angle sequences whose joint motion between
neighbouring points stays within a bound (every joint, shortest way round).
With the configuration flags fixed, this is the continuity of the path: no
flip, no jump. Ties go to the lowest angle index, so the result is a
deterministic function of its inputs.
"""

from __future__ import annotations

import numpy as np


def _wide(qj: np.ndarray, max_step: float) -> bool:
    """Whether two angles of this joint can differ by a whole turn plus at most max_step
    (only then does the shortest way round differ from the plain difference)."""
    finite = qj[np.isfinite(qj)]
    return finite.size > 0 and float(finite.max() - finite.min()) >= 2 * np.pi - max_step


def _reachable(qs: list, wide: list, n: int, max_step: float) -> np.ndarray:
    """(B, A_now, A_prev): every joint moves by at most max_step (shortest way round)
    from point n - 1 to point n; False where an angle is NaN."""
    ok = None
    for qj, w in zip(qs, wide, strict=True):
        d = qj[:, n, :, None] - qj[:, n - 1, None, :]
        if w:
            d -= (2 * np.pi) * np.rint(d * (0.5 / np.pi))
        np.abs(d, out=d)
        ok = d <= max_step if ok is None else np.logical_and(ok, d <= max_step, out=ok)
    return ok


def choose_angles(cost: np.ndarray, q: np.ndarray, max_step: float, mode: str):
    """Best continuous angle sequence per placement.

    Parameters
    ----------
    cost : (B, N, A) per-triple cost, inf where infeasible.
    q : (B, N, A, n) joint angles (rad).
    max_step : largest allowed |q_j(n) - q_j(n-1)| (rad).
    mode : ``"max"`` or ``"compliance"`` (bottleneck) or ``"rms"``.

    Returns
    -------
    (value, index, stuck) : value (B,) objective (inf if no path; rms is the root
    mean square), index (B, N) chosen angle per point, stuck (B,) first point at
    which no feasible continuous sequence reaches (-1 when one exists).
    """
    B, N, A = cost.shape
    square = mode == "rms"
    c = cost**2 if square else cost
    V = c[:, 0].copy()
    back = np.zeros((B, N, A), dtype=np.int32)
    stuck = np.where(np.all(np.isinf(V), axis=1), 0, -1)
    # one contiguous (B, N, A) array per joint: the pair tests below run joint by joint
    qs = [np.ascontiguousarray(q[..., j]) for j in range(q.shape[-1])]
    wide = [_wide(qj, max_step) for qj in qs]
    for n in range(1, N):
        reach = _reachable(qs, wide, n, max_step)
        cand = np.where(reach, V[:, None, :], np.inf)  # (B, A_now, A_prev)
        b = np.argmin(cand, axis=-1)
        best = np.take_along_axis(cand, b[..., None], axis=-1)[..., 0]
        V = best + c[:, n] if square else np.maximum(best, c[:, n])
        back[:, n] = b
        newly = (stuck < 0) & np.all(np.isinf(V), axis=1)
        stuck[newly] = n
    last = np.argmin(V, axis=1)
    value = V[np.arange(B), last]
    if square:
        value = np.sqrt(value / N)
    index = np.zeros((B, N), dtype=np.int32)
    index[:, -1] = last
    for n in range(N - 1, 0, -1):
        index[:, n - 1] = back[np.arange(B), n, index[:, n]]
    return value, index, stuck
