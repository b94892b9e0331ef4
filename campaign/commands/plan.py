"""``campaign plan``: choose the tests of a campaign from its protocol file."""

from __future__ import annotations

from pathlib import Path

import typer

from campaign.cli_common import (
    PANEL_OUTPUT,
    Strategy,
    echo,
    output_dir,
    print_json,
    stage,
    writing_into,
)

#: panels of --help (campaign.cli_common)
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
    import json

    from campaign.options import parse_floats
    from campaign.plan_output import summary_text
    from campaign.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    proto = load_protocol(protocol)
    output_dir(out, force)
    wts = None if weights is None else parse_floats(weights, "--weights")
    with stage(f"candidate evaluation and {strategy} design ({candidates} candidates)"):
        result = make_plan(proto, strategy=str(strategy), seed=seed, candidates=candidates,
                           tests=tests, weights=wts)
    with stage("writing the plan" + ("" if no_figure else " and plan_map.png")), \
            writing_into(out):
        path = write_plan(result, out, figure=not no_figure)
    if as_json:
        summary = json.loads((out / "summary.json").read_text())
        print_json({**summary, "plan_file": str(path)})
        return
    echo(summary_text(result), nl=False)
    echo(f"plan written to {path}")


def register(app: typer.Typer) -> None:
    """Add ``plan`` to the ``campaign`` command line."""
    app.command("plan")(plan)
