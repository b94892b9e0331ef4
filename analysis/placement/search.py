"""The placement grid search: chunks of placements evaluated locally or on Dask.

Why a grid and not an optimizer: the feasible set is not convex and often not
connected (IK branches, joint limits, singularities), the objective is a
maximum over a path (not smooth), and a grid gives the objective map that the
plots show. Every placement is independent, so chunks of placements are the
tasks; a chunk is cut into batches of at most ``max_triples`` (placement,
point, angle) triples, which bounds the memory of a task. The local run and
the Dask run call the same function on the same chunks, so their results are
identical bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from analysis.model.ik import IKSolver
from analysis.placement.evaluate import OK, Problem, evaluate, verify
from analysis.placement.select import choose_angles

#: Reason code of a placement whose points are each feasible but not as one continuous path.
NO_PATH = 5
#: Rounds of "select, verify the chosen triples, strike out failures" before giving up.
MAX_ROUNDS = 20


@dataclass(frozen=True)
class ChunkResult:
    """Per placement: value (objective, inf if infeasible), config (index into
    problem.flags, -1 if infeasible), angle (N,) chosen angle index per point,
    reason (0 feasible, else a reason code of :mod:`analysis.placement.evaluate`
    or NO_PATH), point (the path point where it failed, -1 if feasible)."""

    value: np.ndarray
    config: np.ndarray
    angle: np.ndarray
    reason: np.ndarray
    point: np.ndarray

    @staticmethod
    def concat(parts: list[ChunkResult]) -> ChunkResult:
        return ChunkResult(*(np.concatenate([getattr(p, f) for p in parts])
                             for f in ("value", "config", "angle", "reason", "point")))


def _select_verified(problem, placements, tr, R):
    """choose_angles, then verify the chosen triples and repeat without the failures."""
    cost = tr.cost.copy()
    reason = tr.reason.copy()
    N = cost.shape[1]
    cols = np.arange(N)[None, :]
    for _ in range(MAX_ROUNDS):
        value, index, stuck = choose_angles(cost, tr.q, problem.max_step, problem.objective)
        ok = np.isfinite(value)
        if not np.any(ok):
            break
        sel = np.flatnonzero(ok)
        idx = index[sel]
        q = tr.q[sel[:, None], cols, idx]
        pts = np.broadcast_to(problem.points, (sel.size, N, 3))
        bad = verify(problem, np.broadcast_to(placements[sel, None, :], (sel.size, N, 4)),
                     pts, R[cols, idx], q)
        if not np.any(bad != OK):
            break
        b, n = np.nonzero(bad != OK)
        cost[sel[b], n, idx[b, n]] = np.inf
        reason[sel[b], n, idx[b, n]] = bad[b, n]
    else:
        value = np.where(np.isfinite(value), np.inf, value)  # not settled: refuse
    return value, index, stuck, reason


def _why(reason: np.ndarray, stuck: np.ndarray):
    """(reason code, point) of placements with no path: the most frequent reason among
    the angles at the stuck point, or NO_PATH where that point has feasible angles."""
    B = reason.shape[0]
    at = reason[np.arange(B), np.maximum(stuck, 0)]  # (B, A)
    codes = np.zeros(B, dtype=np.int8)
    for b in range(B):
        if np.any(at[b] == OK):
            codes[b] = NO_PATH
        else:
            codes[b] = np.bincount(at[b], minlength=6).argmax()
    return codes


def evaluate_chunk(problem: Problem, placements: np.ndarray,
                   max_triples: int = 20000) -> ChunkResult:
    """Best configuration and angle sequence for each placement (P, 4) of a chunk."""
    placements = np.asarray(placements, dtype=float).reshape(-1, 4)
    solver = IKSolver.for_robot(problem.robot)
    R = problem.rotations
    N, A = problem.points.shape[0], problem.angles.size
    per = max(1, max_triples // (N * A))
    parts = []
    for start in range(0, placements.shape[0], per):
        pl = placements[start:start + per]
        B = pl.shape[0]
        best = np.full(B, np.inf)
        config = np.full(B, -1, dtype=np.int32)
        angle = np.zeros((B, N), dtype=np.int32)
        far = np.full(B, -1, dtype=np.int32)
        why = np.full(B, 1, dtype=np.int8)
        for c, flags in enumerate(problem.flags):
            tr = evaluate(problem, solver, pl, flags, R)
            value, index, stuck, reason = _select_verified(problem, pl, tr, R)
            better = value < best
            best = np.where(better, value, best)
            config[better] = c
            angle[better] = index[better]
            failed = ~np.isfinite(value)
            stuck = np.where(failed & (stuck < 0), N - 1, stuck)
            further = failed & (stuck > far)
            if np.any(further):
                codes = _why(reason, stuck)
                why[further] = codes[further]
                far[further] = stuck[further]
        ok = np.isfinite(best)
        parts.append(ChunkResult(best, config, angle, np.where(ok, 0, why).astype(np.int8),
                                 np.where(ok, -1, far).astype(np.int32)))
    return ChunkResult.concat(parts)


#: Bytes kept per placement by a search: value (float64), config (int32), reason (int8),
#: point (int32), plus an int32 angle index per path point (:class:`ChunkResult`).
RESULT_BYTES_FIXED = 8 + 4 + 1 + 4
RESULT_BYTES_PER_POINT = 4
#: Tasks in flight on Dask at once: the client holds this many chunks of placements and
#: their results besides the collected arrays, whatever the size of the grid.
DASK_WINDOW = 512


def result_bytes(placements: int, points: int) -> int:
    """Memory (bytes) of the per-placement results of a search of ``placements``."""
    return placements * (RESULT_BYTES_FIXED + RESULT_BYTES_PER_POINT * points)


def chunks_of(placements, chunk: int) -> list[np.ndarray]:
    """Split placements (P, 4) into consecutive chunks of at most ``chunk`` rows."""
    return [placements[i:i + chunk] for i in range(0, len(placements), chunk)]


class _Collector:
    """The results of every placement, filled chunk by chunk in preallocated arrays."""

    def __init__(self, count: int, points: int) -> None:
        self.value = np.empty(count)
        self.config = np.empty(count, dtype=np.int32)
        self.angle = np.empty((count, points), dtype=np.int32)
        self.reason = np.empty(count, dtype=np.int8)
        self.point = np.empty(count, dtype=np.int32)

    def put(self, start: int, part: ChunkResult) -> None:
        sl = slice(start, start + part.value.shape[0])
        for name in ("value", "config", "angle", "reason", "point"):
            getattr(self, name)[sl] = getattr(part, name)

    def result(self) -> ChunkResult:
        return ChunkResult(self.value, self.config, self.angle, self.reason, self.point)


def run_local(problem: Problem, placements, chunk: int,
              progress: Callable[[int, int], None] | None = None) -> ChunkResult:
    """Evaluate every chunk in this process, in order.

    ``placements``: a (P, 4) array or a :class:`analysis.placement.grid.PlacementGrid`,
    whose rows are made one chunk at a time (memory: the results, 17 + 4 N bytes per
    placement, and one chunk).
    """
    total = len(placements)
    out = _Collector(total, problem.points.shape[0])
    count = -(-total // chunk)
    for i, start in enumerate(range(0, total, chunk)):
        out.put(start, evaluate_chunk(problem, placements[start:start + chunk]))
        if progress:
            progress(i + 1, count)
    return out.result()


def run_dask(problem: Problem, placements, chunk: int, client,
             show_progress: bool = False,
             progress: Callable[[int, int], None] | None = None) -> ChunkResult:
    """Evaluate the chunks as tasks of a ``dask.distributed`` client, gathered in order.

    At most :data:`DASK_WINDOW` tasks are submitted at a time, so the client holds a
    bounded number of chunks besides the collected results. ``progress(done, total)``
    is called as each task's result arrives (tasks, not placements); an exception it
    raises stops the search (the futures are released).
    """
    from distributed import as_completed

    problem_f = client.scatter(problem, broadcast=True)
    total = len(placements)
    out = _Collector(total, problem.points.shape[0])
    span = chunk * DASK_WINDOW
    count, done = -(-total // chunk), 0
    for first in range(0, total, span):
        starts = list(range(first, min(total, first + span), chunk))
        pieces = [placements[s:s + chunk] for s in starts]
        futures = client.map(evaluate_chunk, [problem_f] * len(pieces), pieces)
        if show_progress:
            from distributed import progress as progress_bar

            progress_bar(futures)
        where = {f.key: s for f, s in zip(futures, starts, strict=True)}
        try:
            for future in as_completed(futures):
                out.put(where[future.key], future.result())
                done += 1
                if progress:
                    progress(done, count)
        finally:
            client.cancel(futures)
            del futures
    return out.result()
