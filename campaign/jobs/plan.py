"""The ``plan`` job: candidate poses in the protocol's zones, thresholds, the optimal design;
writes the plan directory (plan.csv, the protocol copy, plan_map.png, summary.txt/json)."""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from campaign.jobs.choices import Strategy
from campaign.jobs.option_checks import Stage, floats, no_stage


@dataclass(frozen=True)
class PlanOptions:
    """protocol: the protocol file (.toml/.yaml); out: the plan directory;
    strategy: the design criterion (see ``campaign plan --help``);
    weights: the joints' weights of the relative standard errors (strategy weighted);
    seed: seed of the candidate draw and random design; candidates: candidate poses drawn;
    tests: test poses (None: the protocol's); figure: draw plan_map.png;
    force: write into a non-empty ``out`` (its plan files are replaced);
    map_points: also return the zone map's data (:func:`campaign.planning.map_data.map_points`);
    model: the model class to design for (None: the protocol's ``[campaign] model``)."""

    protocol: Path
    out: Path
    strategy: Strategy = Strategy.worst_joint
    weights: Sequence[float] | None = None
    seed: int = 0
    candidates: int = 10000
    tests: int | None = None
    figure: bool = True
    force: bool = False
    map_points: bool = False
    model: str | None = None


@dataclass
class PlanResult:
    """summary: the document written to OUT/summary.json (SI units); text: summary.txt;
    plan_file: OUT/plan.csv; map: the zone map's data (with ``map_points``)."""

    summary: dict
    text: str
    plan_file: Path
    map: dict | None = None

    def to_json(self) -> dict:
        """The document ``campaign plan --json`` prints."""
        return {**self.summary, "plan_file": str(self.plan_file)}


def run(o: PlanOptions, stage: Stage = no_stage) -> PlanResult:
    """Load the protocol, plan and write the plan directory (removed again on failure)."""
    from analysis.output_files import check_output_dir, created_dir
    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    proto = load_protocol(Path(o.protocol))
    out = Path(o.out)
    check_output_dir(out, o.force)
    wts = None if o.weights is None else floats(o.weights, "--weights")
    strategy = Strategy(o.strategy)
    with stage(f"candidate evaluation and {strategy} design ({o.candidates} candidates)"):
        plan = make_plan(proto, strategy=str(strategy), seed=o.seed, candidates=o.candidates,
                         tests=o.tests, weights=wts, model=o.model)
    with stage("writing the plan" + (" and plan_map.png" if o.figure else "")), \
            created_dir(out):
        path = write_plan(plan, out, figure=o.figure)
    points = None
    if o.map_points:
        from campaign.planning.map_data import map_points

        points = map_points(plan)
    return PlanResult(json.loads((out / "summary.json").read_text()),
                      (out / "summary.txt").read_text(), path, points)
