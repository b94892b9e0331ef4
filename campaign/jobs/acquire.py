"""The ``acquire`` job: run (or resume, or dry-run) a planned campaign on the robot or on the
simulated lab; every reading on disk before the next motion (:mod:`campaign.acquire.session`).

Callable from another process (the GUI runs it in its own): the options record is
plain data (:meth:`AcquireJobOptions.to_dict` / :meth:`from_dict` give JSON), progress
goes to a reporter and, with ``events_file``, one JSON object per line into that file
(``start``, ``phase``, the run's events, ``message``, ``finish``: those of
``campaign acquire --json``). An abort takes the path of Ctrl-C (motion stopped, load
removed, status ``aborted`` recorded): send SIGINT to the process running the job
(:func:`abort`), or pass ``should_abort``, polled at every phase of a test.

``python -m campaign.jobs.acquire OPTIONS.json`` runs the job with the options of that
file (events into its ``events_file``) and prints the result record as JSON; exit
status 0 complete or dry run, 1 aborted or failed, 2 bad input.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

from analysis.errors import InputError
from campaign.acquire.interrupts import AbortRequested, abort_on_sigint

#: the record's fields that are paths
PATH_FIELDS = ("plan", "out", "resume", "events_file")


@dataclass(frozen=True)
class AcquireJobOptions:
    """plan: plan directory of a new run; out: run directory to create (default
    runs/run-<UTC time>); resume: a run directory to continue from its first unfinished
    test; fake: start the simulated lab and run the real drivers against it over
    loopback; assume_yes: the safety confirmation answered (the robot WILL move);
    dry_run: check and list the motions, connect and move nothing; time_scale: the
    simulated lab's time runs this many times faster (--fake only); operator: name
    recorded in the metadata; events_file: JSON lines of progress appended there."""

    plan: Path | None = None
    out: Path | None = None
    resume: Path | None = None
    fake: bool = False
    assume_yes: bool = False
    dry_run: bool = False
    time_scale: float | None = None
    operator: str | None = None
    events_file: Path | None = None

    def to_dict(self) -> dict:
        """JSON-ready (paths as text)."""
        return {k: (str(v) if k in PATH_FIELDS and v is not None else v)
                for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data: dict) -> AcquireJobOptions:
        """The record of :meth:`to_dict`'s document; an unknown key is refused."""
        known = {f.name for f in fields(cls)}
        extra = sorted(set(data) - known)
        if extra:
            raise InputError(f"unknown option(s) {', '.join(extra)}", where="acquire options")
        return cls(**{k: (Path(v) if k in PATH_FIELDS and v is not None else v)
                      for k, v in data.items()})


@dataclass
class AcquireResult:
    """status: complete, dry-run, aborted or failed; reason: why (empty when complete);
    run_dir; ok / failed: test rows measured this session; exported: the Parquet exports
    written; error: the one line of a run record that could not be opened (nothing
    moved), else None."""

    status: str
    reason: str
    run_dir: Path | None
    ok: int = 0
    failed: int = 0
    exported: bool = True
    error: str | None = None

    @property
    def succeeded(self) -> bool:
        """Complete (with its exports) or a dry run: the command's exit status 0."""
        return self.error is None and self.status in ("complete", "dry-run") and self.exported

    def to_json(self) -> dict:
        return {**asdict(self), "run_dir": None if self.run_dir is None else str(self.run_dir)}


def default_run_dir() -> Path:
    """runs/run-<UTC time> (relative to the working directory)."""
    return Path("runs") / time.strftime("run-%Y%m%d-%H%M%S", time.gmtime())


class _Events:
    """A reporter that forwards to ``inner``, appends JSON lines to ``events_file`` and
    turns ``should_abort()`` into the Ctrl-C path (raised once, at a phase change)."""

    def __init__(self, inner, events_file: Path | None, should_abort) -> None:
        from campaign.acquire.progress import JsonReporter

        self.inner, self.should_abort, self.aborted = inner, should_abort, False
        self.stream = None if events_file is None else open(events_file, "a",  # noqa: SIM115
                                                            encoding="utf-8")
        self.lines = None if self.stream is None else JsonReporter(self.stream)

    def __getattr__(self, name: str):  # state, elapsed, remaining: the inner reporter's
        return getattr(self.inner, name)

    def _both(self, name: str, *args, **kwargs) -> None:
        getattr(self.inner, name)(*args, **kwargs)
        if self.lines is not None:
            getattr(self.lines, name)(*args, **kwargs)

    def start(self, info: dict[str, Any]) -> None:
        self._both("start", info)

    def phase(self, **state: Any) -> None:
        self._both("phase", **state)
        if self.should_abort is not None and not self.aborted and self.should_abort():
            self.aborted = True
            raise AbortRequested  # the runner's Ctrl-C path: stop, unload, record

    def event(self, record: dict[str, Any]) -> None:
        self._both("event", record)

    def message(self, text: str) -> None:
        self._both("message", text)

    def finish(self, status: str, reason: str, summary: dict[str, Any]) -> None:
        self._both("finish", status, reason, summary)

    def close(self) -> None:
        self.inner.close()
        if self.stream is not None:
            self.stream.close()
            self.stream = None


def check(o: AcquireJobOptions) -> None:
    """The options' own checks, before any file is read (InputError naming the option):
    --out with --resume, neither --plan nor --resume, --time-scale; the command line and
    the GUI refuse with these same lines."""
    from campaign.acquire.session import check_time_scale

    if o.out is not None and o.resume is not None:
        raise InputError("--out and --resume exclude each other: a resumed run stays in its "
                         "directory", where="campaign acquire")
    if (o.plan is None) == (o.resume is None):
        raise InputError("give either --plan PLAN_DIR (a new run) or --resume RUN_DIR",
                         where="campaign acquire")
    check_time_scale(o.time_scale, o.fake)


def run(o: AcquireJobOptions, reporter=None, say: Callable[[str], None] = print,
        ask: Callable[[str], str] = lambda prompt: "",
        should_abort: Callable[[], bool] | None = None,
        on_event: Callable[[dict[str, Any]], None] | None = None) -> AcquireResult:
    """Run the session; refuse bad input (InputError) before anything is connected.

    ``reporter``: a :class:`campaign.acquire.progress.Reporter` (default: silent);
    ``say``: the motion list and notices; ``ask``: the safety question (default: no
    answer, refused unless ``assume_yes``).
    """
    from campaign.acquire.progress import Reporter
    from campaign.acquire.rundir import WriteFailure, require_new_run_dir
    from campaign.acquire.session import AcquireOptions
    from campaign.acquire.session import acquire as run_session
    from drivers.loopback_guard import loopback_only_mode

    check(o)
    out = None if o.out is None else Path(o.out)
    resume = None if o.resume is None else Path(o.resume)
    plan = None if o.plan is None else Path(o.plan)
    if resume is None and out is None and plan is not None and not o.dry_run:
        out = default_run_dir()
    if out is not None:
        require_new_run_dir(out)
    events = _Events(reporter or Reporter(), None if o.events_file is None
                     else Path(o.events_file), should_abort)
    opts = AcquireOptions(fake=o.fake, assume_yes=o.assume_yes, dry_run=o.dry_run,
                          time_scale=o.time_scale, operator=o.operator)
    try:
        # on the simulated lab every driver talks to this machine only (a copied protocol's
        # instrument addresses must never be tried)
        with loopback_only_mode(o.fake):
            outcome = run_session(plan, out, resume, opts, events, say=say, ask=ask,
                                  on_event=on_event)
    except WriteFailure as err:  # the run's own record cannot be opened (read-only, ...)
        return AcquireResult("failed", f"{err}; nothing moved", out or resume,
                             error=f"{err}; nothing moved")
    finally:
        events.close()
    return AcquireResult(outcome.status, outcome.reason, outcome.run_dir, outcome.ok,
                         outcome.failed, outcome.exported)


def abort(pid: int) -> None:
    """Abort the acquisition running in process ``pid`` (SIGINT: the Ctrl-C path, recorded
    as the Abort button's, :func:`campaign.acquire.interrupts.abort_on_sigint`)."""
    os.kill(pid, signal.SIGINT)


def main(argv: list[str] | None = None) -> int:
    """``python -m campaign.jobs.acquire OPTIONS.json``: run the job in this process."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1:
        print("usage: python -m campaign.jobs.acquire OPTIONS.json", file=sys.stderr)
        return 2
    try:
        options = AcquireJobOptions.from_dict(json.loads(Path(args[0]).read_text()))
        abort_on_sigint()
        result = run(options, say=lambda s: None)
    except InputError as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except json.JSONDecodeError as err:
        print(f"error: {args[0]}: line {err.lineno}: not JSON ({err.msg})", file=sys.stderr)
        return 2
    except OSError as err:
        print(f"error: {err.filename or args[0]}: {err.strerror or err}", file=sys.stderr)
        return 1
    print(json.dumps(result.to_json()))
    return 0 if result.succeeded else 1


if __name__ == "__main__":
    sys.exit(main())
