"""``campaign demo``: the whole chain on the simulated lab with the built-in KR240-2 protocol.

plan -> acquire --fake --yes -> analyze, into one directory: ``OUT/plan``,
``OUT/run`` (the run directory) and ``OUT/run/analysis`` (results and report).
"""

from __future__ import annotations

import time
from pathlib import Path

import typer

from analysis.errors import InputError

PROTOCOL = Path(__file__).resolve().parents[3] / "protocols" / "kr240-2.toml"


def demo(
    out: Path = typer.Option(Path("campaign-demo"), "--out", help="Directory for the plan, "
                             "the run and its analysis (must be new or empty)."),
    quiet: bool = typer.Option(False, "--quiet", help="Only the final lines."),
    report: bool = typer.Option(True, "--report/--no-report", help="Write the HTML/PDF "
                                "report of the analysis."),
) -> None:
    """Plan, acquire on the simulated lab and analyse the KR240-2 campaign (Dumas et al. 2011)."""
    from campaign.acquire.session import AcquireOptions, acquire
    from campaign.cli.commands.acquire import make_reporter
    from campaign.planning.plan_output import summary_text
    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    if not PROTOCOL.is_file():
        raise InputError("the built-in protocol is missing from this installation",
                         where=str(PROTOCOL))
    from analysis.output_files import refuse_link

    refuse_link(out)
    if out.exists() and not out.is_dir():
        raise InputError("exists and is not a directory", where=str(out))
    if out.exists() and any(out.iterdir()):
        raise InputError("demo directory exists and is not empty; choose another --out",
                         where=str(out))
    from campaign.cli.common import echo

    say = (lambda s: None) if quiet else echo
    t0 = time.monotonic()
    protocol = load_protocol(PROTOCOL)
    say(f"1/3 plan: {protocol.campaign.name}")
    plan = make_plan(protocol)
    write_plan(plan, out / "plan", figure=report)
    say(summary_text(plan))
    say("2/3 acquire on the simulated lab (real drivers over loopback)")
    reporter = make_reporter(quiet, False)
    try:
        outcome = acquire(out / "plan", out / "run", None,
                          AcquireOptions(fake=True, assume_yes=True), reporter, say=say)
    finally:
        reporter.close()
    if outcome.status != "complete":
        echo(f"acquisition {outcome.status}: {outcome.reason}", err=True)
        raise typer.Exit(1)
    say("3/3 analyze the run")
    analyze_run(out / "run", report)
    echo(f"demo done in {time.monotonic() - t0:.0f} s: plan {out / 'plan'}, run "
         f"{out / 'run'}, analysis {out / 'run' / 'analysis'}")


def analyze_run(run_dir: Path, report: bool) -> None:
    """``campaign analyze RUN_DIR`` when it exists, else the identification of tests.csv."""
    try:
        import campaign.cli.commands.analyze  # noqa: F401
        import campaign.run_format.reader  # noqa: F401
    except ImportError:
        _analyze_table(run_dir)
        return
    from campaign.cli import main

    status = main(["analyze", str(run_dir), *([] if report else ["--no-report"])])
    if status:
        raise typer.Exit(status)


def _analyze_table(run_dir: Path) -> None:
    """Fallback: identify from the ok rows of tests.csv and print k with its interval."""
    import numpy as np
    import pandas as pd

    from analysis.identification.estimate import analyze_table
    from analysis.identification.measurements import from_csv_frame
    from campaign.protocol import load_protocol
    from campaign.protocol_robot import protocol_robot

    frame = pd.read_csv(run_dir / "tests.csv", dtype={"pose": str})
    frame = frame[frame["status"] == "ok"]
    robot = protocol_robot(load_protocol(run_dir / "protocol.toml"))
    result = analyze_table(from_csv_frame(frame, where=str(run_dir / "tests.csv")), robot)
    for j in range(6):
        typer.echo(f"k{j + 1} = {result.k[j] / 1e3:9.2f} kN m/rad, 95 % interval "
                   f"[{result.ci[j, 0] / 1e3:.2f}, {result.ci[j, 1] / 1e3:.2f}]"
                   if np.isfinite(result.k[j]) else f"k{j + 1}: not identified")


def register(app: typer.Typer) -> None:
    """Add ``demo`` to the ``campaign`` command line."""
    app.command("demo")(demo)
