"""Coverage table of the 95 % intervals of k: the Gaussian methods, or the robust fits.

Seeded Monte-Carlo on the robot file the tests write (``_own_robot.py``: a 6R arm the
project ships no model of), 5 poses x 3 load cases, tracker 30 um / 40 urad per
component, F/T 0.5 N + 0.5 % of reading (``_coverage.NOISE``). With 1000 campaigns the
binomial standard error of a 95 % coverage is 0.69 %, so 95 +- 3 % is resolved.

    PYTHONPATH=. python -m tests.studies.coverage_study [--trials 1000] [--seed 3]
        [--robot arm|z1] [--setup-seed 0]
    PYTHONPATH=. python -m tests.studies.coverage_study --robust [--methods ols wls exact]
        [--modes huber tukey] [--exact-trials 1000] [--write-docs] [--resume DIR]
        [--robot arm|z1] [--scales 1 2] [--data clean glitches]

The first prints the table of ols, wls and exact at the nominal loads and twice them;
``--robust`` the table of Huber and Tukey around ols, wls and exact, on clean campaigns
and on campaigns with glitches (``_coverage.Glitches``: 10 % of the tests with one gross
tracker or F/T error of 20 sigma). Each prints a Markdown table (the ones in
docs/identification.md) and one JSON line; exit 1 if a cell misses 95 +- 3 %.
``--write-docs`` puts the robust table's rows into docs/identification.md (between the
``robust-coverage`` markers; rows of the fits not rerun are kept), so a study split
over runs (``--methods exact`` alone) fills the same table. ``--resume DIR`` saves each
cell's counts and generator states in DIR every 50 campaigns (``_coverage.coverage``
``checkpoint``): a run stopped and started again with the same DIR goes on where it stopped,
and a cell run at fewer campaigns is extended, with the campaigns of one uninterrupted run.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

from tests.studies._coverage import Glitches, campaign_setup, coverage
from tests.studies._own_robot import write_protocol

METHODS = ("ols", "wls", "exact")
ROBUST = ("huber", "tukey")
ROBUST_METHODS = ("ols", "wls", "exact")
#: the robust table in docs/identification.md, between these lines
DOCS = Path(__file__).resolve().parents[2] / "docs" / "identification.md"
BEGIN, END = "<!-- robust-coverage: begin -->", "<!-- robust-coverage: end -->"
HEADER = ("| fit | campaigns | clean, nominal loads: coverage k1..k6 (%) | clean, twice the "
          "loads | glitches, nominal loads | glitches, twice the loads |\n"
          "| --- | --- | --- | --- | --- | --- |")
SCALES = (1.0, 2.0)
#: (label, glitches) of the robust table's data
DATA = (("clean", None), ("glitches", Glitches()))


def _checkpoint(resume: Path | None, name: str) -> Path | None:
    """The checkpoint file of cell ``name`` in ``resume`` (made), or None."""
    if resume is None:
        return None
    resume.mkdir(parents=True, exist_ok=True)
    return resume / f"{name}.json"


def study(trials: int, seed: int, robot_name: str = "arm", setup_seed: int = 0,
          resume: Path | None = None) -> dict:
    """{method: {scale: (coverage (6,), campaigns given)}} of the Gaussian fits, on the
    test-written 6R arm (``robot_name`` "arm") or the Unitree Z1 URDF ("z1",
    :mod:`tests.studies._z1`); ``setup_seed``: the draw of the poses and the truth;
    ``resume``: the directory of the cells' checkpoints."""
    from tests.studies import _z1

    write = {"arm": write_protocol, "z1": _z1.write_protocol}[robot_name]
    with tempfile.TemporaryDirectory() as tmp:
        robot, q, W, k = campaign_setup(write(Path(tmp)), seed=setup_seed)
        return {m: {s: coverage(robot, q, W, k, m, s, trials, seed=seed,
                                checkpoint=_checkpoint(
                                    resume, f"{robot_name}-{setup_seed}-{m}-x{s:g}"))
                    for s in SCALES}
                for m in METHODS}


def robust_study(trials: int, seed: int, methods=ROBUST_METHODS,
                 exact_trials: int | None = None, modes=ROBUST,
                 resume: Path | None = None, robot_name: str = "arm",
                 scales=SCALES, data=tuple(label for label, _ in DATA)) -> dict:
    """{"huber (wls)": {"clean x1": (coverage (6,), given), ...}, ...} of the robust fits;
    ``exact_trials`` campaigns per cell for exact (``trials`` if None); ``robot_name``
    "arm" (the table's) or "z1" (the Unitree Z1 URDF, its poses and truth of setup seed
    0); ``scales``, ``data``: the loads and data ("clean", "glitches") of the cells run."""
    from tests.studies import _z1

    write = {"arm": write_protocol, "z1": _z1.write_protocol}[robot_name]
    prefix = "" if robot_name == "arm" else f"{robot_name}-"
    with tempfile.TemporaryDirectory() as tmp:
        robot, q, W, k = campaign_setup(write(Path(tmp)))
    out = {}
    for m in methods:
        n = trials if m != "exact" or exact_trials is None else exact_trials
        for r in modes:
            row = out[f"{r} ({m})"] = {}
            for label, g in DATA:
                if label not in data:
                    continue
                for s in scales:
                    row[f"{label} x{s:g}"] = coverage(
                        robot, q, W, k, m, s, n, seed=seed, robust=r, glitches=g,
                        checkpoint=_checkpoint(resume, f"{prefix}{r}-{m}-{label}-x{s:g}"))
                    cov, given = row[f"{label} x{s:g}"]
                    print(f"# {r} ({m}) {label} x{s:g}: " + " ".join(f"{100 * c:.1f}"
                                                                    for c in cov)
                          + f" ({given} of {n} given)", file=sys.stderr, flush=True)
    return out


def _cell(cov, given, trials) -> str:
    refused = trials - given
    return (" ".join(f"{100 * c:.1f}" for c in cov)
            + (f" ({refused} refused)" if refused else ""))


def write_docs(rows: dict[str, str], path: Path = DOCS) -> None:
    """Replace (or add) the rows {fit name: Markdown row} of the robust table in ``path``;
    rows of other fits are kept, in the order methods x robust modes."""
    text = path.read_text()
    head, rest = text.split(BEGIN + "\n", 1)
    table, tail = rest.split(END, 1)
    old = {line.split("|")[1].strip().strip("`"): line for line in table.splitlines()
           if line.startswith("| `")}
    old.update(rows)
    order = [f"{r} ({m})" for m in ROBUST_METHODS for r in ROBUST]
    body = "\n".join(old[name] for name in order if name in old)
    path.write_text(f"{head}{BEGIN}\n{HEADER}\n{body}\n{END}{tail}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=1000)
    ap.add_argument("--seed", type=int, default=3)
    ap.add_argument("--robust", action="store_true",
                    help="the robust fits (huber, tukey) on clean data and with glitches")
    ap.add_argument("--methods", nargs="+", choices=ROBUST_METHODS, default=ROBUST_METHODS,
                    help="with --robust: the fits the robust ones reweight")
    ap.add_argument("--modes", nargs="+", choices=ROBUST, default=ROBUST,
                    help="with --robust: the robust modes to run")
    ap.add_argument("--exact-trials", type=int, default=None,
                    help="with --robust: campaigns per cell for exact (default --trials)")
    ap.add_argument("--robot", choices=("arm", "z1"), default="arm",
                    help="the test-written 6R arm, or the Unitree Z1 URDF of "
                         "example-robot-data (with --robust: not with --write-docs)")
    ap.add_argument("--scales", nargs="+", type=float, default=list(SCALES),
                    help="with --robust: the load scales of the cells run (default 1 2)")
    ap.add_argument("--data", nargs="+", choices=[label for label, _ in DATA],
                    default=[label for label, _ in DATA],
                    help="with --robust: clean campaigns, glitched ones, or both")
    ap.add_argument("--setup-seed", type=int, default=0,
                    help="without --robust: seed of the poses and the true stiffness")
    ap.add_argument("--write-docs", action="store_true",
                    help="with --robust: put the rows into docs/identification.md")
    ap.add_argument("--resume", type=Path, default=None, metavar="DIR",
                    help="save each cell's progress in DIR and go on from it")
    args = ap.parse_args(argv)
    if args.robust and args.write_docs and (args.robot != "arm" or args.scales != list(SCALES)
                                            or len(args.data) != len(DATA)):
        print("coverage_study: --write-docs fills the table of the arm's every cell; drop "
              "--robot z1, --scales and --data", file=sys.stderr)
        return 2
    t0 = time.process_time()
    out = {}
    if args.robust:
        res = robust_study(args.trials, args.seed, tuple(args.methods), args.exact_trials,
                           tuple(args.modes), args.resume, args.robot, tuple(args.scales),
                           tuple(args.data))
        cols = [f"{label} x{s:g}" for label, _ in DATA if label in args.data
                for s in args.scales]
        print(HEADER)
        rows = {}
        for name, row in res.items():
            n = (args.exact_trials if name.endswith("(exact)") and args.exact_trials
                 else args.trials)
            rows[name] = (f"| `{name}` | {n} | "
                          + " | ".join(_cell(*row[c], n) for c in cols) + " |")
            print(rows[name])
            for c in cols:
                cov, given = row[c]
                out[f"{name} {c}"] = {"coverage": [round(float(v), 4) for v in cov],
                                      "given": given}
        if args.write_docs:
            write_docs(rows)
    else:
        res = study(args.trials, args.seed, args.robot, args.setup_seed, args.resume)
        print("| method | nominal loads: coverage k1..k6 (%) | twice the loads (%) |")
        print("| --- | --- | --- |")
        for m, by_scale in res.items():
            cells = [_cell(cov, given, args.trials) for cov, given in by_scale.values()]
            for s, (cov, given) in by_scale.items():
                out[f"{m}_x{s:g}"] = {"coverage": [round(float(c), 4) for c in cov],
                                      "given": given}
            print(f"| `{m}` | {cells[0]} | {cells[1]} |")
    worst = max(abs(c - 0.95) for v in out.values() for c in v["coverage"])
    print(json.dumps({"study": "robust coverage" if args.robust else "coverage",
                      "trials": args.trials, "seed": args.seed,
                      "results": out, "worst_deviation_from_95": round(worst, 4),
                      "within_3_percent": worst <= 0.03,
                      "cpu_s": round(time.process_time() - t0, 1)}))
    return 0 if worst <= 0.03 else 1


if __name__ == "__main__":
    sys.exit(main())
