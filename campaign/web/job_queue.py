"""The GUI's queue of long jobs: worker threads, progress, cancellation, a bound.

A :class:`JobQueue` runs at most ``workers`` jobs at a time (one or two on a
two-core machine: the jobs are CPU-bound, and the placement search starts its
own Dask worker processes) and holds at most ``waiting`` more; a job submitted
to a full queue is refused with :class:`QueueFull` (the API answers 429). Each
job runs in a worker thread of the queue; the web API's jobs start a process
there and follow it (:mod:`campaign.web.job_process`).

A job is a function ``work(progress)`` returning the result document (JSON).
``progress.report(fraction, text)`` records its progress (fraction in [0, 1],
or None when the job cannot tell) and is where a cancellation takes effect: once
:meth:`JobQueue.cancel` is asked, the next ``report`` raises :class:`JobCancelled`
(a BaseException, so that no ``except Exception`` of a job swallows it) inside
the job, whose cleanup (``created_dir``, ``replacing``, closing a Dask cluster)
then runs as for any failure. Nothing is kept on disk: the jobs live in
memory, the last :data:`KEEP_FINISHED` finished ones stay readable.
"""

from __future__ import annotations

import collections
import itertools
import secrets
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

#: finished jobs kept for GET /api/jobs/{id} (the oldest are forgotten first)
KEEP_FINISHED = 50
#: states of a job kept for its events (a slow reader misses none but the oldest)
HISTORY = 1000
#: the progress line of a cancelled job (its outputs are removed as a failed one's)
CANCELLED = "cancelled; nothing of it was kept"
#: the states a job ends in
FINAL = ("done", "failed", "cancelled")



class JobCancelled(BaseException):  # noqa: N818 (not an error: a request to stop)
    """Raised inside a job by ``report`` once its cancellation was asked."""


class Progress:
    """What a running job is given: ``report`` (raises JobCancelled once cancelled),
    ``note`` (the same record, never raises: for hooks that must not be interrupted,
    as an acquisition's events) and ``cancelled()``."""

    def __init__(self, queue: JobQueue, job: Job) -> None:
        self._queue, self._job = queue, job

    @property
    def fraction(self) -> float | None:
        """The fraction last reported (None: unknown)."""
        return self._job.fraction

    def cancelled(self) -> bool:
        """Whether the job's cancellation was asked."""
        return self._job.cancel_asked

    def note(self, fraction: float | None, text: str) -> None:
        """Record progress: fraction in [0, 1] (None: unknown), one line of text."""
        with self._queue._lock:
            job = self._job
            job.fraction = None if fraction is None else min(1.0, max(0.0, float(fraction)))
            job.text = text
            job.changed()
            self._queue._lock.notify_all()

    def report(self, fraction: float | None, text: str) -> None:
        """Record progress, or raise JobCancelled when the job's cancellation was asked."""
        if self._job.cancel_asked:
            raise JobCancelled()
        self.note(fraction, text)


class QueueFull(Exception):
    """The queue holds as many jobs as it may; the message says how many."""


@dataclass
class Job:
    """One job: what it is, where it stands, and how it ended.

    state: queued, running, done, failed or cancelled; fraction: progress in
    [0, 1] (None: unknown); text: the latest progress line; result: the result
    document (done); error: ``{"status", "detail", "field", "options"}`` (failed);
    created/started/finished: time.time() seconds; version: counts changes, and
    history keeps the states they lead to (for the server-sent events).
    """

    id: str
    kind: str
    work: Callable[[Progress], dict] = field(repr=False)
    state: str = "queued"
    fraction: float | None = 0.0
    text: str = "waiting in the queue"
    result: dict | None = None
    error: dict | None = None
    created: float = field(default_factory=time.time)
    started: float | None = None
    finished: float | None = None
    cancel_asked: bool = False
    version: int = 0
    history: collections.deque = field(default_factory=lambda: collections.deque(
        maxlen=HISTORY), repr=False)

    def changed(self) -> None:
        """Count a change and keep the state it leads to (for the events; the lock is held)."""
        self.version += 1
        self.history.append((self.version, self.public()))

    def since(self, version: int) -> list[tuple[int, dict]]:
        """(version, state) after ``version``, oldest first (the last :data:`HISTORY` at
        most; the lock is held)."""
        return [(v, state) for v, state in self.history if v > version]

    def public(self) -> dict:
        """The job as the API shows it (no function, times in s since the epoch)."""
        return {"id": self.id, "kind": self.kind, "state": self.state,
                "fraction": self.fraction, "text": self.text, "result": self.result,
                "error": self.error, "created": self.created, "started": self.started,
                "finished": self.finished}


class JobQueue:
    """Jobs run ``workers`` at a time in daemon threads, ``waiting`` more queued.

    ``describe_error(exc)`` turns a job's exception into the ``error`` record, or
    returns None for an exception that is a bug (re-raised in the worker's log
    and recorded as an internal error).
    """

    def __init__(self, workers: int = 1, waiting: int = 3,
                 describe_error: Callable[[BaseException], dict | None] | None = None):
        if workers < 1 or waiting < 0:
            raise ValueError("a job queue needs at least one worker and waiting >= 0")
        self.workers, self.waiting = workers, waiting
        self.describe_error = describe_error or (lambda exc: None)
        self._lock = threading.Condition()
        self._jobs: dict[str, Job] = {}
        self._queue: collections.deque[Job] = collections.deque()
        self._finished: collections.deque[str] = collections.deque()
        self._threads: list[threading.Thread] = []
        self._count = itertools.count(1)

    @property
    def lock(self) -> threading.Condition:
        """The lock every job's record is changed under."""
        return self._lock

    # ---- asking -----------------------------------------------------------------------

    def submit(self, kind: str, work: Callable[[Progress], dict]) -> Job:
        """Queue ``work``; QueueFull when ``workers`` run and ``waiting`` wait already."""
        with self._lock:
            running = sum(j.state == "running" for j in self._jobs.values())
            if running + len(self._queue) >= self.workers + self.waiting:
                raise QueueFull(
                    f"the job queue is full ({running} running, {len(self._queue)} waiting; "
                    f"this server runs {self.workers} at a time and queues {self.waiting}): "
                    "wait for one to finish, or cancel one")
            job = Job(f"{next(self._count)}-{secrets.token_hex(4)}", kind, work)
            job.changed()
            self._jobs[job.id] = job
            self._queue.append(job)
            self._start_workers()
            self._lock.notify_all()
            return job

    def get(self, job_id: str) -> Job | None:
        """The job of that id (None: unknown, or forgotten)."""
        with self._lock:
            return self._jobs.get(job_id)

    def jobs(self) -> list[Job]:
        """Every job known, oldest first."""
        with self._lock:
            return list(self._jobs.values())

    def cancel(self, job_id: str) -> Job | None:
        """Cancel a job: a queued one at once, a running one at its next progress report."""
        with self._lock:
            job = self._jobs.get(job_id)
            if job is None or job.state in FINAL:
                return job
            job.cancel_asked = True
            if job.state == "queued":
                self._queue.remove(job)
                self._end(job, "cancelled", text="cancelled before it started")
            else:
                job.text = "cancelling"
                job.changed()
            self._lock.notify_all()
            return job

    def wait(self, job_id: str, version: int, timeout: float) -> Job | None:
        """The job once its version differs from ``version`` (or after ``timeout`` s)."""
        with self._lock:
            self._lock.wait_for(lambda: (j := self._jobs.get(job_id)) is None
                                or j.version != version, timeout)
            return self._jobs.get(job_id)

    # ---- running ----------------------------------------------------------------------

    def _start_workers(self) -> None:
        self._threads = [t for t in self._threads if t.is_alive()]
        while len(self._threads) < self.workers:
            t = threading.Thread(target=self._worker, name=f"gui-job-{len(self._threads)}",
                                 daemon=True)
            self._threads.append(t)
            t.start()

    def _worker(self) -> None:
        while True:
            with self._lock:
                self._lock.wait_for(lambda: self._queue, timeout=None)
                job = self._queue.popleft()
                job.state, job.started, job.text = "running", time.time(), "started"
                job.changed()
                self._lock.notify_all()
            self._run(job)

    def _run(self, job: Job) -> None:
        progress = Progress(self, job)
        try:
            result = job.work(progress)
        except JobCancelled as stop:
            with self._lock:
                self._end(job, "cancelled", text=str(stop) or CANCELLED)
            return
        except BaseException as exc:  # noqa: BLE001 (a job's failure is its record)
            error = self.describe_error(exc)
            if error is None:
                error = {"status": 500, "detail": f"internal error: {type(exc).__name__}: "
                         f"{str(exc).splitlines()[0] if str(exc) else ''}",
                         "field": None, "options": {}}
            with self._lock:
                cancelled = job.cancel_asked
                self._end(job, "cancelled" if cancelled else "failed",
                          text=CANCELLED if cancelled
                          else error["detail"], error=None if cancelled else error)
            if error["status"] == 500 and not isinstance(exc, Exception):
                raise
            return
        with self._lock:
            if job.cancel_asked:  # asked after its last report: the result stands
                job.cancel_asked = False
            self._end(job, "done", text="done", result=result, fraction=1.0)

    def _end(self, job: Job, state: str, text: str, result: dict | None = None,
             error: dict | None = None, fraction: float | None = None) -> None:
        """Record the end (the lock is held)."""
        job.state, job.text, job.result, job.error = state, text, result, error
        if fraction is not None:
            job.fraction = fraction
        job.finished = time.time()
        job.work = _gone
        job.changed()
        self._finished.append(job.id)
        while len(self._finished) > KEEP_FINISHED:
            self._jobs.pop(self._finished.popleft(), None)
        self._lock.notify_all()


def _gone(progress: Progress) -> Any:  # the finished job's function is released
    raise RuntimeError("this job has ended")
