"""Where ``campaign place`` runs its search: this process, a local Dask cluster it
starts, or the Dask scheduler given with ``--scheduler``; the probe runs there too.

The local cluster's worker processes get one BLAS/OpenMP thread each (two workers
on two cores, no threads beside them) and a ``malloc`` that keeps its memory: Dask
sets ``MALLOC_TRIM_THRESHOLD_=65536`` in its workers by default, which turns off
glibc's adaptive mmap threshold, so every numpy temporary above 128 KiB is mapped
and unmapped afresh. On the README example that was 40 % of the workers' CPU in
system time (1.7-1.9 s of 4.6 s per worker), against 0.24 s without it (issue 36).
glibc's own adaptive tuning still trimmed the heap's top and faulted it in again
between temporaries: at rest, the 1e8 search's workers spent 11 s of 77 s CPU in
system time (25 % of the wall). With the mmap threshold at 64 MiB, the trim threshold
at 128 MiB and 64 MiB of top pad (:data:`WORKER_ENVIRON`; at most ~128 MiB kept free
per worker): 0.6 s, and the search 15 % faster (40.8 -> 34.8 s, same machine, at rest).
Dask's statistical profiler is off in these workers: its thread samples every
thread's stack each 10 ms, which cost 13-17 % of a worker's CPU on top of the task's
own (process against thread CPU time of a 204-placement task of the README example,
8 tasks; 5-8 % with it off: the heartbeats, memory monitor and communication); the
search never reads the profile.
A ``--scheduler``'s workers were started by someone else, with their own settings.
"""

from __future__ import annotations

import os
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from analysis.errors import InputError
from analysis.placement.probe import ProbeResult, chunk_peak_bytes, chunk_seconds

#: The environment of the local cluster's worker processes (set before they start).
WORKER_ENVIRON = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1",
                  "OPENBLAS_NUM_THREADS": "1",
                  # glibc keeps the search's numpy temporaries (a few MB each) on its heap:
                  # mapped afresh above the mmap threshold, or returned to the kernel by a
                  # trim and faulted in again, they cost the workers 13 % of their CPU in
                  # system time at rest (1e8 search: 11 s of 77 s)
                  "MALLOC_MMAP_THRESHOLD_": str(64 << 20),
                  "MALLOC_TRIM_THRESHOLD_": str(128 << 20),
                  "MALLOC_TOP_PAD_": str(64 << 20)}


@dataclass(frozen=True)
class SearchRunner:
    """The place a search runs: ``how`` (words for the output), ``workers`` (processes
    evaluating at once), ``startup_seconds`` (starting or reaching the cluster, s; 0 in
    this process) and ``client`` (the Dask client, None in this process)."""

    how: str
    workers: int
    startup_seconds: float
    client: object | None

    def probe(self, problem, sample) -> ProbeResult:
        """Time ``sample`` (placements, (n, 4)) untraced and trace its peak memory
        separately, where the search runs (on two workers at once when there are two)."""
        n = int(sample.shape[0])
        if self.client is None:
            wall, cpu = chunk_seconds(problem, sample)
            return ProbeResult(n, wall, chunk_peak_bytes(problem, sample), cpu)
        # its own key (hash=False): run_dask scatters the same problem, and releasing one
        # of two futures of a shared key loses the data under the other
        problem_f = self.client.scatter(problem, broadcast=True, hash=False)
        timed = self.client.submit(chunk_seconds, problem_f, sample, pure=False)
        peak = self.client.submit(chunk_peak_bytes, problem_f, sample, pure=False)
        wall, cpu = timed.result()
        return ProbeResult(n, float(wall), int(peak.result()), float(cpu))

    def cpu_seconds(self) -> float:
        """CPU seconds (user + system, every thread) used so far by the processes that
        evaluate: the workers' sum on Dask, this process's own without."""
        if self.client is None:
            return time.process_time()
        return float(sum(self.client.run(time.process_time).values()))

    def run(self, problem, G, chunk: int, progress: Callable[[int, int], None] | None):
        """Every placement of ``G`` in tasks of ``chunk``: the search's ChunkResult."""
        from analysis.placement.search import run_dask, run_local

        if self.client is None:
            return run_local(problem, G, chunk, progress)
        return run_dask(problem, G, chunk, self.client, show_progress=progress is None,
                        progress=progress)


#: samples of the run queue and the seconds between them (:func:`other_runnable`)
QUEUE_SAMPLES, QUEUE_INTERVAL = 25, 0.008


def other_runnable(proc_loadavg: str = "/proc/loadavg") -> tuple[float, str]:
    """(processes of others runnable now, how it was measured): the mean of
    :data:`QUEUE_SAMPLES` readings of the kernel's count of runnable tasks (the fourth
    field of ``/proc/loadavg``, "running/total"), less this process, over about 0.2 s.
    Not the 1-minute load average: it lags by a minute, so it still counts the work that
    just ended (a benchmark's earlier phases, the command's own imports), and an idle
    machine read at a load of 2 halved every estimate (measured: x2.03-2.08 on the
    README example and a 1e8 search, at rest). Where the file is absent (not Linux), the
    1-minute load average."""
    counts = []
    try:
        for i in range(QUEUE_SAMPLES):
            with open(proc_loadavg, encoding="ascii") as f:
                counts.append(int(f.read().split()[3].split("/")[0]))
            if i + 1 < QUEUE_SAMPLES:
                time.sleep(QUEUE_INTERVAL)
    except (OSError, IndexError, ValueError):
        load = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
        return load, f"at a 1-minute load average of {load:.2g}"
    others = max(0.0, sum(counts) / len(counts) - 1.0)
    return others, f"with {others:.2g} other runnable processes (run queue, mean of " \
                   f"{len(counts)} readings)"


@contextmanager
def search_runner(scheduler: str | None, workers: int | None) -> Iterator[SearchRunner]:
    """This process (``workers == 0`` and no scheduler), the Dask cluster at
    ``scheduler``, or a local cluster of ``workers`` processes (default: the cores),
    closed on exit with its scratch directory."""
    if workers == 0 and not scheduler:
        yield SearchRunner("in this process (no Dask)", 1, 0.0, None)
        return
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    cluster = scratch = None
    if scheduler:
        try:
            client = Client(scheduler, timeout=10)
        except (OSError, TimeoutError) as err:
            raise InputError(f"cannot reach the Dask scheduler ({err})",
                             where="--scheduler") from None
        n = max(1, sum(w.get("nthreads", 1) for w in
                       client.scheduler_info()["workers"].values()))
        how = f"Dask cluster at {scheduler}"
    else:
        import dask

        n = workers or os.cpu_count() or 1
        # the workers' scratch space (Dask's dask-scratch-space) in a directory of this
        # search's own, removed with it: nothing left in the system's temporary directory
        scratch = tempfile.TemporaryDirectory(prefix="campaign-place-",
                                              ignore_cleanup_errors=True)
        with dask.config.set({"temporary-directory": scratch.name,
                              "distributed.nanny.pre-spawn-environ": dict(WORKER_ENVIRON),
                              "distributed.worker.profile.enabled": False}):
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   host="127.0.0.1", dashboard_address=None,
                                   local_directory=scratch.name)
        client = Client(cluster)
        how = f"local Dask cluster, {n} worker processes"
    try:
        yield SearchRunner(how, n, time.perf_counter() - t0, client)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        if scratch is not None:
            scratch.cleanup()
