"""``campaign acquire``: run a planned campaign on the robot, or on the simulated lab."""

from __future__ import annotations

import sys
import time
from pathlib import Path

import typer

from analysis.errors import InputError
from campaign.cli_common import echo


def make_reporter(quiet: bool, json_lines: bool):
    """Reporter for the chosen output mode (rich panel by default)."""
    from campaign.acquire.progress import JsonReporter, QuietReporter, RichReporter

    if quiet and json_lines:
        raise InputError("choose one of --quiet and --json", where="campaign acquire")
    if json_lines:
        return JsonReporter()
    if quiet:
        return QuietReporter()
    return RichReporter()


def acquire(
    plan: Path | None = typer.Option(None, "--plan", help="Plan directory (campaign plan)."),
    fake: bool = typer.Option(False, "--fake", help="Start the simulated lab and run the real "
                              "drivers against it over loopback."),
    out: Path | None = typer.Option(None, "--out", help="Run directory to create "
                                    "(default runs/run-<UTC time>)."),
    resume: Path | None = typer.Option(None, "--resume", help="Continue this run directory "
                                       "from its first unfinished test."),
    yes: bool = typer.Option(False, "--yes", help="Answer the safety confirmation (the robot "
                             "WILL move)."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Check and print the motions, "
                                 "connect nothing, move nothing."),
    quiet: bool = typer.Option(False, "--quiet", help="Print only the final status."),
    json_lines: bool = typer.Option(False, "--json", help="JSON lines on stdout for scripts."),
    time_scale: float | None = typer.Option(None, "--time-scale", help="Simulated lab only: "
                                            "its time runs this many times faster."),
    operator: str | None = typer.Option(None, "--operator", help="Name recorded in the "
                                        "metadata (default: login name)."),
) -> None:
    """Measure every planned test: approach, settle, tare, unloaded pose, load, wrench and
    loaded pose, unload, unloaded pose again; every reading on disk before the next motion.

    Exit status: 0 complete, 1 aborted or failed (the run directory says why and can be
    resumed with --resume), 2 bad input or a plan refused by the safety checks.
    """
    from campaign.acquire.session import AcquireOptions
    from campaign.acquire.session import acquire as run_acquire

    if resume is None and out is None and plan is not None and not dry_run:
        out = Path("runs") / time.strftime("run-%Y%m%d-%H%M%S", time.gmtime())
    if out is not None and resume is not None:
        raise InputError("--out and --resume exclude each other: a resumed run stays in its "
                         "directory", where="campaign acquire")
    if out is not None:
        from campaign.acquire.rundir import require_new_run_dir

        require_new_run_dir(out)
    reporter = make_reporter(quiet, json_lines)
    say = (lambda s: reporter.message(s)) if json_lines else echo
    if quiet:
        def say(s: str) -> None:
            pass
    if (quiet or json_lines) and not yes and not dry_run:
        # a person is asked to confirm: the motion list and the question go to stderr,
        # whatever the output mode (stdout stays machine-readable)
        def say(s: str) -> None:
            echo(s, err=True)

    def ask(prompt: str) -> str:
        typer.echo(prompt, err=True, nl=False)
        return sys.stdin.readline()  # "" at end of input: refused

    opts = AcquireOptions(fake=fake, assume_yes=yes, dry_run=dry_run, time_scale=time_scale,
                          operator=operator)
    from campaign.acquire.rundir import WriteFailure

    try:
        outcome = run_acquire(plan, out, resume, opts, reporter, say=say, ask=ask)
    except WriteFailure as err:  # the run's own record cannot be opened (read-only, ...)
        reporter.close()
        typer.echo(f"error: {err}; nothing moved", err=True)
        raise typer.Exit(1) from None
    finally:
        reporter.close()
    if outcome.status not in ("complete", "dry-run") or not outcome.exported:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add ``acquire`` to the ``campaign`` command line."""
    app.command("acquire")(acquire)
