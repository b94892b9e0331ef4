"""``campaign demo``: the whole chain on the simulated lab with the shipped KR240-2 protocol.

plan -> acquire --fake --yes -> analyze, into one directory: ``OUT/plan``,
``OUT/run`` (the run directory) and ``OUT/run/analysis`` (results and report).
The work is :mod:`campaign.jobs.demo`; this module parses the options and presents.
"""

from __future__ import annotations

from pathlib import Path

import typer

from campaign.cli.terminal import echo, print_json, stage


def demo(
    out: Path = typer.Option(Path("campaign-demo"), "--out", help="Directory for the plan, "
                             "the run and its analysis (must be new or empty)."),
    protocol: Path | None = typer.Option(None, "--protocol", help="Protocol file with a "
                                         "[fake_lab] table (default: the shipped "
                                         "kr240-2.toml)."),
    tests: int | None = typer.Option(None, "--tests", help="Test poses (default: the "
                                     "protocol's)."),
    candidates: int = typer.Option(10000, "--candidates", help="Candidate poses the planner "
                                   "draws."),
    time_scale: float | None = typer.Option(None, "--time-scale", help="Simulated time runs "
                                            "this many times faster (default: the "
                                            "protocol's)."),
    quiet: bool = typer.Option(False, "--quiet", help="Only the final lines."),
    report: bool = typer.Option(True, "--report/--no-report", help="Write the HTML/PDF "
                                "report of the analysis."),
    as_json: bool = typer.Option(False, "--json", help="Print the three jobs' results as "
                                 "one JSON document (SI units)."),
) -> None:
    """Plan, acquire on the simulated lab and analyse the KR240-2 campaign (Dumas et al. 2011)."""
    from rich.console import Console

    from campaign.acquire.progress import Reporter
    from campaign.cli.commands.acquire import make_reporter
    from campaign.cli.commands.analyze import _print_assumptions
    from campaign.jobs.demo import DemoOptions, run

    quiet = quiet or as_json
    console = Console(stderr=as_json)
    # with --json, stdout carries the JSON document only (no final status line)
    reporter = Reporter() if as_json else make_reporter(quiet, False)
    try:
        result = run(DemoOptions(out, protocol, report, tests, candidates, time_scale),
                     say=(lambda s: None) if quiet else echo, stage=stage, reporter=reporter,
                     on_assumptions=None if quiet else lambda a: _print_assumptions(console, a),
                     warn=lambda line: echo(line, err=True))
    finally:
        reporter.close()
    _present(console, result, out, quiet, as_json)


def _present(console, result, out: Path, quiet: bool, as_json: bool) -> None:
    """The JSON document, or the analysis' table and the closing line; exit 1 when the
    acquisition did not complete. Quiet: the analysis' warnings only (on stderr)."""
    from campaign.cli.commands.analyze import _print

    if as_json:
        print_json(result.to_json())
    acquired, done = result.acquisition, result.analysis
    if not result.succeeded:
        echo(f"acquisition {acquired.status}: {acquired.error or acquired.reason}", err=True)
        raise typer.Exit(1)
    if quiet:
        for w in done.identification.warnings[done.early_warnings:]:
            echo(f"warning: {w}", err=True)
    else:
        _print(console, done.identification, done.files, printed=done.early_warnings)
    if not as_json:
        echo(f"demo done in {result.elapsed_s:.0f} s: plan {out / 'plan'}, run "
             f"{out / 'run'}, analysis {out / 'run' / 'analysis'}")

def register(app: typer.Typer) -> None:
    """Add ``demo`` to the ``campaign`` command line."""
    app.command("demo")(demo)
