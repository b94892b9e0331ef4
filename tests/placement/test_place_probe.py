"""The placement search's probe and where it runs (issue 36): a sample spread over the
grid, tasks sized from the probe, and local Dask workers with one BLAS thread and
a malloc that keeps its memory (not Dask's MALLOC_TRIM_THRESHOLD_=65536, whose system time
was 40 % of the workers' CPU)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.model.robots import load_robot
from analysis.placement.grid import PlacementGrid
from analysis.placement.probe import (
    ProbeResult,
    batch_placements,
    chunk_peak_bytes,
    core_share,
    expected_seconds,
    probe_sample,
    task_chunk,
)
from analysis.placement.search import run_local
from campaign.use.place_cluster import WORKER_ENVIRON, search_runner
from tests.placement.test_place import _problem


def test_probe_sample_spans_the_grid_in_order():
    grid = PlacementGrid(np.arange(10.0), np.arange(5.0), np.array([0.3]), np.array([0.0]))
    full = grid.full()
    sample = probe_sample(grid, 7)
    index = np.linspace(0, 49, 7).round().astype(int)
    np.testing.assert_array_equal(sample, full[index])
    assert np.array_equal(sample[0], full[0]) and np.array_equal(sample[-1], full[-1])
    assert probe_sample(grid, 500).shape == (50, 4)  # never more than the grid
    assert probe_sample(full[:1], 34).shape == (1, 4)


@pytest.mark.parametrize(("seconds", "placements", "workers", "want"), [
    (0.27, 819, 2, 102),  # README example: 2 s of work is 238, 4 tasks/worker caps at 102
    (0.27, 21021, 2, 238),  # ~1e8 evaluations: 7 batches of 34 (1.9 s per task)
    (5.0, 21021, 2, 34),  # slow placements: one batch per task, never a short one
    (0.27, 20, 2, 3),  # fewer placements than a batch: 4 tasks per worker
    (0.27, 1, 8, 1),
])
def test_task_chunk(seconds, placements, workers, want):
    probe = ProbeResult(34, seconds, 1)
    chunk = task_chunk(probe, placements, workers, 34)
    assert chunk == want
    assert 1 <= chunk <= placements
    if chunk >= 34:
        assert chunk % 34 == 0


@pytest.mark.parametrize(("load", "workers", "cores", "share"), [
    (0.0, 2, 2, 1.0),  # a quiet machine: a core each
    (0.0, 1, 2, 1.0),
    (2.0, 2, 2, 0.5),  # two others always runnable: four processes on two cores
    (6.0, 2, 2, 0.25),  # the shared development machine at load 6
    (1.0, 4, 8, 1.0),
])
def test_core_share(load, workers, cores, share):
    assert core_share(load, workers, cores) == pytest.approx(share, rel=1e-12)


def test_expected_seconds_from_cpu_time_share_and_tail():
    # 34 placements in 0.17 s of CPU (0.9 s of wall: not used), 819 placements, tasks
    # of 102, 2 workers at a quarter of a core: 0.005 s / 0.25 = 0.02 s per placement;
    # work 819 x 0.02 / 2 = 8.19 s; tail: half a task (102 x 0.02 = 2.04 s) on one of
    # two workers, 2.04 / 4 = 0.51 s
    probe = ProbeResult(34, 0.9, 1, 0.17)
    assert expected_seconds(probe, 819, 2, 102, 0.25) == pytest.approx(8.19 + 0.51, rel=1e-12)
    # one worker: no tail; no CPU time: the wall time stands in
    assert expected_seconds(probe, 819, 1, 102, 1.0) == pytest.approx(819 * 0.005, rel=1e-12)
    assert expected_seconds(ProbeResult(34, 0.17, 1), 819, 1, 102, 1.0) == pytest.approx(
        819 * 0.005, rel=1e-12)
    # a task larger than a worker's share: the tail is bounded by the share
    assert expected_seconds(probe, 10, 2, 10, 1.0) == pytest.approx(0.025 + 0.025 / 4)


def test_batch_placements_matches_evaluate_chunk_default():
    assert batch_placements(16, 36) == 20000 // (16 * 36) == 34
    assert batch_placements(1000, 360) == 1


def test_peak_is_traced_and_tracing_is_restored():
    import tracemalloc

    problem = _problem(load_robot("kr240-2"), None, None)
    G = np.array([[1.6, 0.0, 0.3, 0.0], [1.8, 0.2, 0.3, 0.5]])
    assert not tracemalloc.is_tracing()
    peak = chunk_peak_bytes(problem, G)
    assert not tracemalloc.is_tracing()
    # at least the (placements x points x angles x configurations) joint angles it holds
    assert peak >= 2 * 1 * 12 * 6 * 8


def test_local_workers_environment_and_same_results(tmp_path, monkeypatch):
    """The local cluster's worker sees one BLAS thread and the project's malloc settings
    (the trim threshold 128 MiB, not Dask's 64 KiB);
    its search equals the one in this process bit for bit."""
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.delenv("MALLOC_TRIM_THRESHOLD_", raising=False)
    problem = _problem(load_robot("kr240-2"), None, None)
    G = np.array([[x, y, 0.3, 0.0] for x in (1.4, 1.8, 2.2) for y in (-0.3, 0.3)])
    with search_runner(None, 1) as runner:
        assert runner.workers == 1 and runner.client is not None

        def env():
            import os

            return {k: os.environ.get(k) for k in (*WORKER_ENVIRON, "MALLOC_TRIM_THRESHOLD_")}

        seen = next(iter(runner.client.run(env).values()))

        def profiling():
            import dask

            return dask.config.get("distributed.worker.profile.enabled")

        profiled = next(iter(runner.client.run(profiling).values()))
        probed = runner.probe(problem, G[:3])
        res = runner.run(problem, G, 2, lambda done, total: None)  # no text bar
    assert seen == WORKER_ENVIRON
    assert seen["MALLOC_TRIM_THRESHOLD_"] == str(128 * 2**20)  # not Dask's default 65536
    assert profiled is False  # Dask's 10 ms stack sampler is off in the search's workers
    assert probed.placements == 3 and probed.seconds > 0 and probed.peak_bytes > 0
    assert probed.cpu_seconds is not None and probed.cpu_seconds > 0
    ref = run_local(problem, G, 6)
    for f in ("value", "config", "angle", "reason", "point"):
        np.testing.assert_array_equal(getattr(res, f), getattr(ref, f))


def test_in_process_runner():
    problem = _problem(load_robot("kr240-2"), None, None)
    G = np.array([[1.6, 0.0, 0.3, 0.0], [1.8, 0.2, 0.3, 0.5]])
    with search_runner(None, 0) as runner:
        assert runner.client is None and runner.workers == 1
        assert runner.startup_seconds == 0.0
        probed = runner.probe(problem, G)
        res = runner.run(problem, G, 1, None)
    assert probed.placements == 2
    np.testing.assert_array_equal(res.value, run_local(problem, G, 2).value)
