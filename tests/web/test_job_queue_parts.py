"""The job queue and the error records on their own: order, bound, cancellation at a
progress report, a bug recorded as one line; command-line options mapped to fields."""

from __future__ import annotations

import threading
import time

import pytest

from campaign.web.job_errors import describe, option_field
from campaign.web.job_queue import KEEP_FINISHED, JobQueue, QueueFull


def _wait(q: JobQueue, job_id: str) -> str:
    end = time.monotonic() + 10
    while time.monotonic() < end:
        job = q.get(job_id)
        if job.state in ("done", "failed", "cancelled"):
            return job.state
        time.sleep(0.005)
    raise AssertionError(job.state)


def test_jobs_run_in_order_one_at_a_time_and_the_bound_holds():
    q = JobQueue(workers=1, waiting=2)
    gate = threading.Event()
    order = []

    def work(name):
        def run(progress):
            gate.wait(5)
            order.append(name)
            progress.report(1.0, f"{name} done")
            return {"name": name}
        return run

    jobs = [q.submit("t", work(n)) for n in "abc"]
    with pytest.raises(QueueFull, match=r"1 running, 2 waiting|0 running, 3 waiting"):
        q.submit("t", work("d"))
    gate.set()
    assert [_wait(q, j.id) for j in jobs] == ["done"] * 3
    assert order == ["a", "b", "c"]
    assert q.get(jobs[1].id).result == {"name": "b"}
    assert [s["state"] for _, s in q.get(jobs[0].id).since(0)] == ["queued", "running",
                                                                   "running", "done"]


def test_cancel_takes_effect_at_the_next_report_and_cleanup_runs():
    q = JobQueue(workers=1, waiting=1)
    started, cleaned = threading.Event(), []

    def run(progress):
        try:
            for i in range(1000):
                started.set()
                time.sleep(0.01)
                progress.report(i / 1000, f"step {i}")
        finally:
            cleaned.append(True)
        return {}

    job = q.submit("t", run)
    started.wait(5)
    q.cancel(job.id)
    assert _wait(q, job.id) == "cancelled"
    assert cleaned == [True] and q.get(job.id).result is None


def test_a_bug_is_one_line_and_old_jobs_are_forgotten():
    q = JobQueue(workers=1, waiting=KEEP_FINISHED + 5)

    def bug(progress):
        raise ZeroDivisionError("division by zero\nmore")

    first = q.submit("t", bug)
    assert _wait(q, first.id) == "failed"
    assert q.get(first.id).error == {"status": 500, "detail": "internal error: "
                                     "ZeroDivisionError: division by zero", "field": None,
                                     "options": {}}
    later = [q.submit("t", lambda p: {}) for _ in range(KEEP_FINISHED)]
    _wait(q, later[-1].id)
    assert q.get(first.id) is None and q.get(later[-1].id) is not None


@pytest.mark.parametrize(("option", "field"), [
    ("--force", "force"), ("--x-mm", "x_mm"), ("--wrench", "wrench_N_Nm"),
    ("--translation-sigma-um", "translation_sigma_m"), ("--tests", "tests"),
    ("--joint-stiffness", "joint_stiffness_Nm_per_rad"), ("--nothing", None),
])
def test_options_map_to_fields(option, field):
    names = ["force", "x_mm", "wrench_N_Nm", "translation_sigma_m", "tests",
             "joint_stiffness_Nm_per_rad", "out"]
    assert option_field(option, names) == field


def test_a_refusal_names_its_field_and_options(tmp_path):
    from dataclasses import dataclass
    from pathlib import Path

    from analysis.errors import InputError

    @dataclass
    class Opts:
        out: Path
        force: bool = False

    err = InputError("output directory exists and is not empty; choose another or add "
                     "--force to overwrite its files", where=f"--out {tmp_path}/o")
    rec = describe(err, tmp_path, Opts(out=tmp_path / "o"))
    assert rec == {"status": 400, "detail": "--out o: output directory exists and is not "
                   "empty; choose another or add --force to overwrite its files",
                   "field": "out", "options": {"--out": "out", "--force": "force"}}
    assert describe(KeyError("x"), tmp_path) is None  # a bug is not a refusal
    full = describe(OSError(28, "No space left on device", f"{tmp_path}/o/a.csv"), tmp_path)
    assert full["status"] == 409 and full["detail"] == "o/a.csv: No space left on device"
