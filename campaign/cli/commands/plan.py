"""``campaign plan``: choose the tests of a campaign from its protocol file."""

from __future__ import annotations

from pathlib import Path

import typer

from campaign.cli.terminal import PANEL_OUTPUT, Strategy, echo, print_json, stage

#: panels of --help (campaign.cli.terminal)
_DESIGN = "Design"


def plan(
    protocol: Path = typer.Option(..., "--protocol", "-p", help="Protocol file (.toml/.yaml)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output directory of the plan."),
    strategy: Strategy = typer.Option(
        "worst-joint", "--strategy", metavar="<strategy>",  # the choices are in the help:
        # as one word they would fold mid-word at 80 columns
        help="One of: worst-joint (default): smallest largest relative standard error of k "
             "(no joint worse than the median random zone design); weighted: smallest "
             "--weights-weighted sum of the relative standard errors; d-optimal (max log det "
             "of the information); e-optimal (max smallest eigenvalue); zones-random "
             "(random poses in the zones).", rich_help_panel=_DESIGN,
    ),
    weights: str = typer.Option(None, "--weights",
                                help="Weights of the joints' relative standard errors, "
                                     "comma-separated (with --strategy weighted).",
        rich_help_panel=_DESIGN),
    seed: int = typer.Option(0, "--seed", help="Seed of the candidate draw and random design.",
        rich_help_panel=_DESIGN),
    candidates: int = typer.Option(10000, "--candidates", help="Candidate poses drawn.",
        rich_help_panel=_DESIGN),
    tests: int = typer.Option(None, "--tests", help="Test poses (default: the protocol's).",
        rich_help_panel=_DESIGN),
    model: str = typer.Option(None, "--model", metavar="<class>",
                              help="Model class to design for (default: the protocol's "
                                   "[campaign] model, else joints): joints, links, compensator "
                                   "or compensator+links; the summary then predicts the se of "
                                   "its parameters too.",
        rich_help_panel=_DESIGN),
    no_figure: bool = typer.Option(False, "--no-figure", help="Skip plan_map.png.",
        rich_help_panel=PANEL_OUTPUT),
    force: bool = typer.Option(False, "--force", help="Write into a non-empty --out "
                               "(its plan files are replaced).", rich_help_panel=PANEL_OUTPUT),
    as_json: bool = typer.Option(False, "--json", help="Print summary.json (SI units) "
                                 "instead of the text summary.", rich_help_panel=PANEL_OUTPUT),
) -> None:
    """Plan the tests: candidate poses in the zones, thresholds, optimal design.

    Writes OUT/plan.csv (angles in degrees, wrench in N and N m), the protocol
    copy, OUT/plan_map.png and OUT/summary.txt/json, and prints the predicted
    standard error of every joint stiffness beside that of a random zone design.
    """
    from campaign.jobs.plan import PlanOptions, run
    from campaign.options import numbers_option

    wts = numbers_option(weights, "--weights")
    result = run(PlanOptions(protocol, out, strategy, wts, seed, candidates, tests,
                             not no_figure, force, model=model), stage=stage)
    if as_json:
        print_json(result.to_json())
        return
    echo(result.text, nl=False)
    echo(f"plan written to {result.plan_file}")


def register(app: typer.Typer) -> None:
    """Add ``plan`` to the ``campaign`` command line."""
    app.command("plan")(plan)
