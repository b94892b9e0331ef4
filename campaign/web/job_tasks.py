"""What each queued job of ``/api/jobs`` runs in its process: the job with its hooks.

One module-level function per job (pickled by name into the job's process, see
:mod:`campaign.web.job_process`): ``task(progress, options, *extra)`` calls the
job's ``run`` with its progress hooks turned into the job's progress
(:mod:`campaign.web.progress_hooks`) and returns its result record.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from campaign.web import progress_hooks
from campaign.web.job_queue import JobCancelled


def plan(progress, options):
    """The plan job; its stages as progress."""
    from campaign.jobs.plan import run

    return run(options, stage=progress_hooks.stage(progress))


def plan_for_the_form(progress, options, keys: tuple[str, ...]):
    """The plan job of the Plan view's form: its stages as progress; its result as the view
    shows it (rows, zone map); a refusal with each line mapped to the form's ``keys``."""
    from analysis.errors import InputError
    from campaign.jobs.plan import run
    from campaign.web.plan_api import form_refusal, planned

    try:
        result = run(options, stage=progress_hooks.stage(progress))
    except InputError as err:
        raise form_refusal(err, list(keys)) from None
    return planned(result, options.protocol)


def maps(progress, options):
    """The maps job; its stages and notes as progress."""
    from campaign.jobs.maps import run

    return run(options, stage=progress_hooks.stage(progress),
               note=progress_hooks.say(progress))


def compensate(progress, options):
    """The compensate job (no steps of its own to report)."""
    from campaign.jobs.compensate import run

    progress.report(None, "compensating the path" + (
        " and replaying it on the simulated lab" if options.verify_fake else ""))
    return run(options)


def place(progress, options, server_limit: float):
    """The place job: each task of the search as progress, its lines as text."""
    from campaign.jobs.place import run

    return run(options, progress_hooks.console(progress), progress.report, server_limit)


def robustness(progress, options):
    """The robustness job: the simulated campaigns identified, counted."""
    from campaign.jobs.robustness import run

    def counted(done: int, total: int) -> None:
        progress.report(done / total, f"{done} of {total} simulated campaigns identified")

    return run(options, progress=counted, note=progress_hooks.say(progress))


@dataclass(frozen=True)
class Analyzed:
    """The analyze job's result and the report's verdict line ({"kind", "text"}), which the
    Analyze view shows above k."""

    result: Any
    verdict: dict

    def to_json(self) -> dict:
        """The job's document (results.json, analysis.json, the files) and ``verdict``."""
        return {**self.result.to_json(), "verdict": self.verdict}


def analyze(progress, options):
    """The analyze job; its stages and a damaged run's warnings as progress; its result
    with the report's verdict line (the run's own notes are in analysis.json)."""
    from analysis.report.verdict import verdict
    from campaign.jobs.analyze import run

    result = run(options, stage=progress_hooks.stage(progress),
                 warn=progress_hooks.say(progress))
    v = verdict(result.identification, [])
    return Analyzed(result, {"kind": v.kind, "text": v.text})


def acquire(progress, options, lock=None, robot: str | None = None):
    """The acquire job: its phases as progress; a cancellation takes its Ctrl-C path.
    ``lock``: the robot's claim file (:mod:`campaign.web.acquire_rule`), held by this
    process while the acquisition runs (refused when another acquisition holds it)."""
    import os

    from campaign.web.acquire_rule import claim

    held = None if lock is None else claim(lock, robot)
    try:
        return _acquire(progress, options)
    finally:
        if held is not None:
            os.close(held)


def _acquire(progress, options):
    from campaign.jobs.acquire import run

    result = run(options, reporter=progress_hooks.AcquireProgress(progress),
                 say=lambda s: None, should_abort=progress.cancelled)
    if progress.cancelled():
        raise JobCancelled(f"cancelled: the acquisition was stopped (motion stopped, load removed) "
                           f"({result.status}: {result.reason}); the run stays, resumable")
    return result
