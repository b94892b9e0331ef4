"""A queued job run in a process of its own, supervised from the queue's worker thread.

Why a process: the jobs are CPU-bound and use libraries that are not made for
threads (matplotlib draws their figures), and some tune the interpreter (the
analysis freezes the garbage collector's heap); in a process each has its own,
and the server stays responsive. The process is started with ``spawn`` (no
copy of the server's threads) and is not a daemon, so that the placement
search can start its own Dask worker processes in it.

The two ends talk over a pipe: the child sends ``("progress", fraction, text)``
as the job reports and one final message, ``("done", document)``,
``("refused", record)``, ``("cancelled", text)`` or ``("bug", line)``; the
parent sends ``"cancel"`` once the job's cancellation is asked, and the child's
next progress report raises :class:`~campaign.web.job_queue.JobCancelled` there,
so that the job's own cleanup runs. A child that does not end within
:data:`CANCEL_GRACE` s of it is terminated.
"""

from __future__ import annotations

import atexit
import multiprocessing
import os
import signal
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from campaign.web.job_queue import JobCancelled, Progress

#: seconds a job's process has to end once cancelled, before it is terminated
CANCEL_GRACE = 30.0
#: the job processes running now: interrupted when the server exits (multiprocessing
#: would otherwise wait for them, the processes not being daemons)
LIVE: set = set()


def _interrupt_live() -> None:
    """At the server's exit, SIGINT each job process (its Ctrl-C path: its cleanup runs)."""
    for proc in list(LIVE):
        try:
            os.kill(proc.pid, signal.SIGINT)
        except (OSError, TypeError):
            continue
    for proc in list(LIVE):
        proc.join(10)
        if proc.is_alive():
            proc.kill()


class ProcessFailed(Exception):
    """The job's process ended with a refusal (``record``) or a bug (``record`` None)."""

    def __init__(self, text: str, record: dict | None = None) -> None:
        super().__init__(text)
        self.record = record


class ChildProgress:
    """The :class:`~campaign.web.job_queue.Progress` of a job in its process."""

    def __init__(self, pipe) -> None:
        self.pipe, self._cancelled, self.fraction = pipe, False, 0.0

    def cancelled(self) -> bool:
        """Whether the parent asked to cancel (read from the pipe without waiting)."""
        while not self._cancelled and self.pipe.poll(0):
            self._cancelled = self.pipe.recv() == "cancel"
        return self._cancelled

    def note(self, fraction: float | None, text: str) -> None:
        self.fraction = fraction
        self.pipe.send(("progress", fraction, text))

    def report(self, fraction: float | None, text: str) -> None:
        if self.cancelled():
            raise JobCancelled()
        self.note(fraction, text)


def _ended(task: Callable, ws: Path, options, extra: tuple, progress) -> tuple:
    """Run ``task(progress, options, *extra)``; how it ended, as the child's last message."""
    from campaign.jobs.choices import json_ready
    from campaign.web.job_errors import describe, relative_to_workspace

    try:
        result = task(progress, options, *extra)
        return ("done", relative_to_workspace(ws, json_ready(result.to_json())))
    except JobCancelled as stop:
        return ("cancelled", str(stop))
    except Exception as err:  # noqa: BLE001 (how the job ended is the message)
        record = describe(err, ws, options)
        if record is not None:
            return ("refused", record)
        first = str(err).splitlines()[0] if str(err) else ""
        return ("bug", f"internal error: {type(err).__name__}: {first}")


def _stop(signum, frame) -> None:
    raise KeyboardInterrupt  # SIGTERM as Ctrl-C: the job's cleanup runs


def _child(pipe, task: Callable, ws: Path, options, extra: tuple) -> None:
    """The job process: run the task and send how it ended. SIGINT and SIGTERM interrupt
    it as Ctrl-C does (even when the server was started with SIGINT ignored)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _stop)
    try:
        pipe.send(_ended(task, ws, options, extra, ChildProgress(pipe)))
    except KeyboardInterrupt:  # interrupted: the job's cleanup has run; nothing to send
        return
    finally:
        pipe.close()


def _outcome(message: tuple) -> Any:
    """The result document of a last message, or its exception raised."""
    kind = message[0]
    if kind == "done":
        return message[1]
    if kind == "refused":
        raise ProcessFailed(message[1]["detail"], message[1])
    if kind == "cancelled":
        raise JobCancelled(*(() if not message[1] else (message[1],)))
    raise ProcessFailed(message[1])


def run_in_thread(task: Callable, ws: Path, options, progress: Progress,
                  extra: tuple = ()) -> Any:
    """As :func:`run_in_process`, in the calling thread (no isolation: for tests, where
    a process per job would only add its start-up time)."""
    return _outcome(_ended(task, ws, options, extra, progress))


def run_in_process(task: Callable, ws: Path, options, progress: Progress,
                   extra: tuple = ()) -> Any:
    """Run ``task(progress, options, *extra)`` (a module-level function: it is pickled by
    name) in a new process; its result document (JSON, workspace paths relative), or
    JobCancelled / ProcessFailed."""
    ctx = multiprocessing.get_context("spawn")
    parent, child = ctx.Pipe(duplex=True)
    proc = ctx.Process(target=_child, args=(child, task, ws, options, extra), daemon=False,
                       name="campaign-gui-job")
    proc.start()
    if not LIVE:  # registered after multiprocessing's own exit hook, so that it runs first
        atexit.unregister(_interrupt_live)
        atexit.register(_interrupt_live)
    LIVE.add(proc)
    child.close()
    asked = None  # when the cancellation was sent (time.monotonic())
    try:
        while True:
            if asked is None and progress.cancelled():
                parent.send("cancel")
                asked = time.monotonic()
            if asked is not None:
                if time.monotonic() - asked > CANCEL_GRACE:
                    proc.terminate()
                    raise JobCancelled()
            if not parent.poll(0.1):
                if not proc.is_alive() and not parent.poll(0):
                    raise ProcessFailed(f"internal error: the job's process ended without "
                                        f"an answer (exit code {proc.exitcode})")
                continue
            try:
                message = parent.recv()
            except EOFError:
                raise ProcessFailed(f"internal error: the job's process ended without an "
                                    f"answer (exit code {proc.exitcode})") from None
            if message[0] == "progress":
                progress.note(message[1], message[2])
            else:
                return _outcome(message)
    finally:
        proc.join(CANCEL_GRACE)
        if proc.is_alive():
            proc.kill()
            proc.join(5)
        LIVE.discard(proc)
        parent.close()
