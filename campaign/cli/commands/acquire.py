"""``campaign acquire``: run a planned campaign on the robot, or on the simulated lab."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from analysis.errors import InputError
from campaign.cli.terminal import echo


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
    from campaign.jobs.acquire import AcquireJobOptions, run

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

    result = run(AcquireJobOptions(plan, out, resume, fake, yes, dry_run, time_scale, operator),
                 reporter, say=say, ask=ask)
    if result.error is not None:
        typer.echo(f"error: {result.error}", err=True)
        raise typer.Exit(1)
    if not result.succeeded:
        raise typer.Exit(1)


def register(app: typer.Typer) -> None:
    """Add ``acquire`` to the ``campaign`` command line."""
    app.command("acquire")(acquire)
