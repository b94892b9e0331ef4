"""The timed probe of a placement search: a sample of placements evaluated where the
search will run, for its time, its memory, and the size of its tasks.

Three things kept the earlier probe from predicting its search (issue 36): it took
the first placements of the grid (one corner of the box, often mostly infeasible
and cheap), it was timed with ``tracemalloc`` on (1.8-2.3x slower than the search,
measured on the KR240-2 README example), and it ran in the command's process while
the search ran in Dask worker processes. Here the sample is spread over the whole
grid, the time is measured untraced, the peak memory traced in a separate call, and
both are functions a Dask worker can run (the search's own conditions).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from analysis.placement.search import evaluate_chunk

#: (placement, point, angle) triples :func:`evaluate_chunk` evaluates at once (its default).
BATCH_TRIPLES = 20000
#: Seconds of work a search task is sized to: Dask's cost per task is a few
#: milliseconds (scheduling, sending the placements and results), under 1 % of this.
TASK_SECONDS = 2.0
#: Tasks per worker at least, so the last wave leaves a worker idle for at most a
#: quarter of a task's share (load balance across placements of unequal cost).
TASKS_PER_WORKER = 4


def batch_placements(points: int, angles: int) -> int:
    """Placements :func:`evaluate_chunk` evaluates at once (at least one)."""
    return max(1, BATCH_TRIPLES // (points * angles))


def probe_sample(G, count: int) -> np.ndarray:
    """``count`` placements (count, 4) spread evenly over the grid ``G`` (a (P, 4) array
    or a :class:`analysis.placement.grid.PlacementGrid`), first and last included."""
    n = len(G)
    count = max(1, min(count, n))
    index = np.unique(np.linspace(0, n - 1, count).round().astype(np.int64))
    return np.stack([np.asarray(G[int(i)], dtype=float) for i in index])


def chunk_seconds(problem, placements: np.ndarray) -> float:
    """Wall-clock seconds (``time.perf_counter``) of :func:`evaluate_chunk` on
    ``placements``, untraced: what one search task of these placements costs. The
    first placement is evaluated once before, untimed: a fresh worker's first call
    pays one-time costs (imports, first use of numpy's kernels) the search does not."""
    evaluate_chunk(problem, placements[:1])
    t0 = time.perf_counter()
    evaluate_chunk(problem, placements)
    return time.perf_counter() - t0


def chunk_peak_bytes(problem, placements: np.ndarray) -> int:
    """Peak bytes allocated (``tracemalloc``; numpy reports its buffers to it) by
    :func:`evaluate_chunk` on ``placements``; tracing slows it, so it is not timed."""
    import tracemalloc

    was = tracemalloc.is_tracing()
    if not was:
        tracemalloc.start()
    tracemalloc.reset_peak()
    base = tracemalloc.get_traced_memory()[0]
    evaluate_chunk(problem, placements)
    peak = tracemalloc.get_traced_memory()[1] - base
    if not was:
        tracemalloc.stop()
    return int(peak)


@dataclass(frozen=True)
class ProbeResult:
    """A timed probe: ``placements`` evaluated in ``seconds`` (wall clock, untraced),
    with a peak allocation of ``peak_bytes`` (bytes)."""

    placements: int
    seconds: float
    peak_bytes: int

    @property
    def seconds_per_placement(self) -> float:
        return self.seconds / self.placements


def task_chunk(probe: ProbeResult, placements: int, workers: int, batch: int) -> int:
    """Placements per search task: about :data:`TASK_SECONDS` of work at the probe's
    rate, a whole number of ``batch`` (evaluate_chunk's batch: no short batches), and
    at least :data:`TASKS_PER_WORKER` tasks per worker where the grid allows."""
    per_s = max(probe.seconds_per_placement, 1e-9)
    want = batch * max(1, math.floor(TASK_SECONDS / (per_s * batch)))
    share = -(-placements // (TASKS_PER_WORKER * max(1, workers)))
    if share < want:
        want = batch * (share // batch) if share >= batch else share
    return max(1, min(want, placements))
