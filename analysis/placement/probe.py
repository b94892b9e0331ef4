"""The timed probe of a placement search: a sample of placements evaluated where the
search will run, for its time, its memory, and the size of its tasks.

Three things kept the earlier probe from predicting its search (issue 36): it took
the first placements of the grid (one corner of the box, often mostly infeasible
and cheap), it was timed with ``tracemalloc`` on (1.8-2.3x slower than the search,
measured on the KR240-2 README example), and it ran in the command's process while
the search ran in Dask worker processes. Here the sample is spread over the whole
grid, the time is measured untraced, the peak memory traced in a separate call, and
both are functions a Dask worker can run (the search's own conditions).

A fourth, on a shared machine (issue 36, measured on the README example at load
averages of 5-6 on 2 cores): the probe's wall time is a fraction of a second, and a
short burst from a sleeping process gets more than its fair share of a busy core,
so the probe ran at 40-60 % of a core's speed while the search's workers got 25-35 %
each: estimates 1.0-3.8x off the search, either way, from one run to the next. The
search's own costs besides the evaluations were small beside that: the workers were
busy 94 % of the search's wall time (the rest: the last task's tail, task hand-over),
and the command's process (scheduler and client) used 0.3 s of CPU in 5-8 s.
So the estimate (:func:`expected_seconds`) takes the probe's CPU time per placement
(steadier: 3.9-4.9 ms per placement on the README example at those loads) and
divides it by the share of a core each worker can expect from the other processes
runnable before the search started (:func:`core_share`; the command reads the kernel's run
queue, not the 1-minute load average, which lags by a minute and halved the estimate on
an idle machine just after other work), and adds the tail.
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


def chunk_seconds(problem, placements: np.ndarray) -> tuple[float, float]:
    """(wall-clock seconds (``time.perf_counter``), CPU seconds of the calling thread
    (``time.thread_time``)) of :func:`evaluate_chunk` on ``placements``, untraced: what
    one search task of these placements costs. The first placement is evaluated once
    before, untimed: a fresh worker's first call pays one-time costs (imports, first use
    of numpy's kernels) the search does not.

    The thread's time, not the process's: a freshly started Dask worker's own threads
    (registration, memory monitor) added 10-40 % of CPU time to the process in the
    probe's fraction of a second (README example, load average 7), against 5-8 % over
    the search's tasks; the thread's time per placement matched the search's within
    10 %."""
    evaluate_chunk(problem, placements[:1])
    t0, c0 = time.perf_counter(), time.thread_time()
    evaluate_chunk(problem, placements)
    return time.perf_counter() - t0, time.thread_time() - c0


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
    """A timed probe: ``placements`` evaluated in ``seconds`` (wall clock, untraced) and
    ``cpu_seconds`` (CPU time of the evaluating thread; None where not measured), with
    a peak allocation of ``peak_bytes`` (bytes)."""

    placements: int
    seconds: float
    peak_bytes: int
    cpu_seconds: float | None = None

    @property
    def seconds_per_placement(self) -> float:
        """Wall seconds per placement."""
        return self.seconds / self.placements

    @property
    def cpu_seconds_per_placement(self) -> float:
        """CPU seconds per placement (the wall seconds where the CPU time is unknown)."""
        return (self.seconds if self.cpu_seconds is None else self.cpu_seconds) / self.placements


def core_share(load: float, workers: int, cores: int) -> float:
    """Fraction of one core (0-1] each of ``workers`` busy processes can expect when
    ``load`` other processes (the run queue before the search) are runnable
    on ``cores`` cores, the kernel sharing the cores evenly among all of them."""
    return min(1.0, cores / max(float(load) + workers, 1e-9))


def expected_seconds(probe: ProbeResult, placements: int, workers: int, chunk: int,
                     share: float) -> float:
    """Wall seconds a search of ``placements`` in tasks of ``chunk`` is expected to take
    on ``workers`` processes that each get ``share`` of a core: the probe's CPU seconds
    per placement x placements / workers / share, plus the last wave's tail: on average
    half a task, on all but one worker, (workers - 1) / (2 workers) of a task."""
    per = probe.cpu_seconds_per_placement / max(share, 1e-9)
    work = per * placements / max(1, workers)
    task = per * min(chunk, placements)
    return work + 0.5 * min(task, work) * (workers - 1) / max(1, workers)


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
