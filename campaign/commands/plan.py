"""``campaign plan``: choose the tests of a campaign from its protocol file."""

from __future__ import annotations

from pathlib import Path

import typer

# Kept in step with campaign.planner.STRATEGIES (checked by a test): the planner pulls in
# pandas and every command module is imported when the command line starts.
STRATEGIES = ("worst-joint", "weighted", "d-optimal", "e-optimal", "zones-random")


def plan(
    protocol: Path = typer.Option(..., "--protocol", "-p", help="Protocol file (.toml/.yaml)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output directory of the plan."),
    strategy: str = typer.Option(
        "worst-joint", "--strategy",
        help=f"One of {', '.join(STRATEGIES)}. worst-joint: smallest largest relative standard "
             "error of k (no joint worse than the median random zone design); weighted: "
             "smallest --weights-weighted sum of the relative standard errors."
    ),
    weights: str = typer.Option(None, "--weights",
                                help="Weights of the joints' relative standard errors, "
                                     "comma-separated (with --strategy weighted)."),
    seed: int = typer.Option(0, "--seed", help="Seed of the candidate draw and random design."),
    candidates: int = typer.Option(10000, "--candidates", help="Candidate poses drawn."),
    tests: int = typer.Option(None, "--tests", help="Test poses (default: the protocol's)."),
    no_figure: bool = typer.Option(False, "--no-figure", help="Skip plan_map.png."),
) -> None:
    """Plan the tests: candidate poses in the zones, thresholds, optimal design.

    Writes OUT/plan.csv (angles in degrees, wrench in N and N m), the protocol
    copy, OUT/plan_map.png and OUT/summary.txt/json, and prints the predicted
    standard error of every joint stiffness beside that of a random zone design.
    """
    from campaign.options import parse_floats
    from campaign.plan_output import summary_text
    from campaign.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    proto = load_protocol(protocol)
    wts = None if weights is None else parse_floats(weights, "--weights")
    result = make_plan(proto, strategy=strategy, seed=seed, candidates=candidates, tests=tests,
                       weights=wts)
    path = write_plan(result, out, figure=not no_figure)
    typer.echo(summary_text(result), nl=False)
    typer.echo(f"plan written to {path}")


def register(app: typer.Typer) -> None:
    """Add ``plan`` to the ``campaign`` command line."""
    app.command("plan")(plan)
