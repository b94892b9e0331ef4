"""Study of ``campaign analyze --model auto`` on the shop lab (issue 32); writes its table
into docs/identification.md ("Model classes").

Rerun: ``python -m tests.studies.model_class_study --campaigns 100 --write-docs``, or in
shards (``--seed S --campaigns N --labs all --jsonl FILE`` each, then ``--table FILE...
--write-docs``)
(from the repository root; about 4.5 s of CPU per all-effects campaign and 1.1 s per
clean one; the JSON lines of the 100 + 100 campaigns in docs/identification.md are in
tests/studies/results/). Each campaign: 12 poses sampled in the KR240-2 zones x the first
3 load cases of protocols/kr240-2-shop.toml, the realistic-arm physics of its [fake_lab]
(:mod:`analysis.identification.studies.model_classes`), noise as declared. Two labs: all
effects (gravity, links 2-3, lost motion, the axis-2 compensator, its geometry given to
the analysis), and clean (joint springs only). ``--design plan:DIR`` replaces the sampled
poses by the tests of the plan directory DIR (``campaign plan``), the same for every seed
(:func:`~analysis.identification.studies.model_classes.plan_design`); the table then has a
row per lab per design.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from analysis.identification.studies import model_classes as mc

DOCS = Path(__file__).resolve().parents[2] / "docs" / "identification.md"
BEGIN, END = "<!-- model-classes: begin -->", "<!-- model-classes: end -->"
HEADER = ("| lab | campaigns | accepted | true class chosen | 95 % intervals cover | "
          "held-out chi2/nu (median; in [0.8, 1.25]) | median k error vs the lab's k, "
          "k1..k6 |\n| --- | --- | --- | --- | --- | --- | --- |")


def run(lab_name: str, campaigns: int, poses: int, seed0: int,
        jsonl: Path | None = None, design: mc.Design | None = None) -> tuple[str, list]:
    """Campaigns seed0.. of one lab, on sampled poses or the fixed ``design``: (the
    table's row, their outcomes)."""
    robot, lab, k, loads, noise = mc.shop_lab()
    if lab_name == "clean":
        lab = replace(lab, links=(), lost_motion=None, compensator=None, gravity="off")
    extra = {} if design is None else {"design": design.label}  # sampled: lines as before
    out = []
    for seed in range(seed0, seed0 + campaigns):
        o = mc.one_campaign(robot, lab, k, loads, poses, noise, seed, design)
        print(f"# {lab_name} {seed}: {o.chosen} accepted={o.accepted} "
              f"covered {o.covered}/{o.total} held-out {o.heldout_chi2_nu:.3f}",
              file=sys.stderr, flush=True)
        if jsonl is not None:  # one line per campaign: shards run apart, joined by --table
            with jsonl.open("a") as fh:
                fh.write(json.dumps({"lab": lab_name, "seed": seed, **extra, **asdict(o),
                                     "k_error": o.k_error.tolist()}) + "\n")
        out.append(o)
    return row(lab_name, out, extra.get("design")), out


def rows_from(paths: list[Path]) -> list[str]:
    """The table's rows from the campaigns' JSON lines (``--jsonl``) of one or more
    shards, a row per lab per design (sampled poses first, then the designs as the files
    give them; all effects first)."""
    by_lab: dict[tuple, list] = {}
    for path in paths:
        for line in path.read_text().splitlines():
            d = json.loads(line)
            key = (d.pop("design", None), d.pop("lab"))
            d.pop("seed")
            d["k_error"] = np.array(d["k_error"], float)
            by_lab.setdefault(key, []).append(mc.Outcome(**d))
    # the designs in the order the files give them
    designs = [None] + list(dict.fromkeys(dz for dz, _ in by_lab if dz is not None))
    return [row(lab, by_lab[dz, lab], dz) for dz in designs for lab in ("all", "clean")
            if (dz, lab) in by_lab]


def row(lab_name: str, out: list, design: str | None = None) -> str:
    """The table's row of one lab's campaigns (``design``: the fixed design's label, None
    for sampled poses)."""
    n = len(out)
    acc = np.mean([o.accepted for o in out])
    true = np.mean([o.chosen == o.true_class for o in out])
    cov = sum(o.covered for o in out) / max(sum(o.total for o in out), 1)
    ho = np.array([o.heldout_chi2_nu for o in out])
    inside = np.mean((ho >= 0.8) & (ho <= 1.25))
    kerr = np.nanmedian(np.array([o.k_error for o in out]), axis=0)
    label = "all effects" if lab_name == "all" else "clean (joint springs)"
    if design is not None:
        label += f", {design}"
    return (f"| {label} | {n} | {100 * acc:.0f} % | {100 * true:.0f} % "
            f"({out[0].true_class}) | {100 * cov:.1f} % | {np.median(ho):.3f}; "
            f"{100 * inside:.0f} % | {' '.join(f'{100 * e:+.1f}' for e in kerr)} % |")


def write_docs(rows: list[str], path: Path = DOCS) -> None:
    text = path.read_text()
    head, rest = text.split(BEGIN + "\n", 1)
    _, tail = rest.split(END, 1)
    path.write_text(f"{head}{BEGIN}\n{HEADER}\n" + "\n".join(rows) + f"\n{END}{tail}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--campaigns", type=int, default=100)
    ap.add_argument("--poses", type=int, default=12)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--labs", nargs="+", choices=("all", "clean"), default=["all", "clean"])
    ap.add_argument("--write-docs", action="store_true")
    ap.add_argument("--jsonl", type=Path, help="append each campaign's outcome here")
    ap.add_argument("--design", default="sampled", metavar="sampled|plan:DIR",
                    help="sampled: --poses zone poses per seed x the first 3 load cases "
                         "(default); plan:DIR: the tests of the plan directory DIR "
                         "(campaign plan), the same for every seed")
    ap.add_argument("--table", type=Path, nargs="+",
                    help="no campaign: the table from these --jsonl files (shards)")
    a = ap.parse_args(argv)
    if a.design != "sampled" and not a.design.startswith("plan:"):
        ap.error("--design: sampled or plan:DIR")
    design = None if a.design == "sampled" else mc.plan_design(a.design[len("plan:"):])
    rows = []
    if a.table:
        rows = rows_from(a.table)
        print("\n".join(rows), flush=True)
    for lab in a.labs if not a.table else ():
        r, _ = run(lab, a.campaigns, a.poses, a.seed, a.jsonl, design)
        print(r, flush=True)
        rows.append(r)
    if a.write_docs:
        write_docs(rows)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
