"""Benchmark of the command line's start-up: CPU time of the commands against baselines.

Run: ``python benchmarks/bench_startup.py [--repeats N]``. Each command runs in
a new process; its CPU time (user + system, from ``getrusage(RUSAGE_CHILDREN)``)
is compared with a baseline timed the same way in the same run:

* ``campaign --help`` against the fastest program that prints the same list: a
  one-file typer app (:func:`minimal_app`) with the same thirteen commands, their
  help lines and the ``--version`` option, nothing else imported; the two
  outputs' command lists must be equal line for line (limit 1.5x);
* every ``campaign <cmd> --help`` against that app's ``<cmd> --help`` (the
  command's help line only, no options: typer's own floor for a command's help,
  less work than ours, so the ratio is an upper bound); each run also reports
  which heavy libraries (numpy, scipy, pinocchio, pandas, matplotlib, pyarrow,
  fastapi, dask) the process imported: none, or the benchmark stops;
* ``campaign stiffness --robot kr240-2 --q 0,30,10,45,45,45`` (one pose) against
  ``python -c "import numpy, typer, rich, pinocchio"``, what any program doing
  that work with these libraries pays before its first line (limit 2.5x).

Commands and baselines alternate, best of N each, so that load from other jobs
on the machine hits both sides alike. The outputs are checked: ``--help`` must
list every command module (and the same lines as the baseline app), and the
stiffness command's ``--json`` output (run once, untimed) must match the
library's K_X and deflection. The last line printed is one JSON object of the
figures.
"""

from __future__ import annotations

import argparse
import json
import os
import pkgutil
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _load import LoadWindow

STIFFNESS_ARGS = ["stiffness", "--robot", "kr240-2", "--q", "0,30,10,45,45,45"]
STIFFNESS_REFERENCE = "import numpy, typer, rich, pinocchio"
#: CPU ratio limits: campaign --help / the minimal app's, campaign stiffness / its imports
HELP_LIMIT, STIFFNESS_LIMIT = 1.5, 2.5
#: libraries that no ``--help`` may import (tens to hundreds of ms of CPU each)
HEAVY = ("numpy", "scipy", "pinocchio", "pandas", "matplotlib", "pyarrow", "fastapi", "dask")
#: a fresh interpreter runs ``campaign ARGS`` and prints the heavy modules it imported
PROBE = """
import contextlib, io, json, sys
from campaign.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    status = main(sys.argv[1:])
print(json.dumps([status, sorted({{m.split('.')[0] for m in sys.modules}} & set({heavy!r}))]))
"""


def minimal_app(path: Path) -> Path:
    """Write the baseline of ``campaign --help``: a one-file typer app with the commands and
    help lines of :data:`campaign.cli.app.LAZY_COMMANDS` and a ``--version`` option, set up as
    campaign's app is (no completion, no pretty exceptions), and nothing else."""
    from campaign.cli.app import LAZY_COMMANDS

    lines = ["import typer", "",
             "app = typer.Typer(name='campaign', help='Plan, run and analyse joint-stiffness "
             "identification campaigns of serial robots.', no_args_is_help=True, "
             "add_completion=False, pretty_exceptions_enable=False)", "",
             "@app.callback()",
             "def _root(version: bool = typer.Option(False, '--version', is_eager=True, "
             "help='Print the version and exit.')) -> None:",
             "    pass", ""]
    for i, (name, (_, help_line)) in enumerate(sorted(LAZY_COMMANDS.items())):
        lines += [f"@app.command({name!r}, help={help_line!r})", f"def _c{i}() -> None:",
                  "    pass", ""]
    lines += ["app()", ""]
    path.write_text("\n".join(lines))
    return path


def commands_panel(text: str) -> list[str]:
    """The lines of the Commands panel of a ``--help`` text."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if "Commands" in line)
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith("╰"))
    return lines[start:end + 1]


def heavy_imports(args: list[str]) -> list[str]:
    """The heavy libraries a fresh ``campaign ARGS`` imports (untimed; exit 0 required)."""
    proc = subprocess.run([sys.executable, "-c", PROBE.format(heavy=HEAVY), *args],
                          capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        raise SystemExit(f"campaign {' '.join(args)} failed: {proc.stderr.strip()}")
    status, heavy = json.loads(proc.stdout.strip().splitlines()[-1])
    if status != 0:
        raise SystemExit(f"campaign {' '.join(args)} exited {status}")
    return heavy


def campaign_command() -> list[str]:
    """The installed console script beside this interpreter, else ``python -m campaign``."""
    script = Path(sys.executable).with_name("campaign")
    if script.is_file():
        return [str(script)]
    found = shutil.which("campaign")
    return [found] if found else [sys.executable, "-m", "campaign"]


def run(cmd: list[str]) -> tuple[float, float, str]:
    """(CPU s, wall s, stdout) of one child process; a failure stops the benchmark."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300,
                          env={**os.environ, "COLUMNS": "80"})
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}): {proc.stderr.strip()}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall, proc.stdout


def check_help(text: str) -> None:
    import campaign.cli.commands

    names = [m.name for m in pkgutil.iter_modules(campaign.cli.commands.__path__)]
    missing = [n for n in names if f" {n} " not in text]
    if missing:
        raise SystemExit(f"campaign --help does not list: {', '.join(missing)}")


def check_stiffness(campaign: list[str]) -> None:
    """The command's numbers against the library (imports here do not touch the timings)."""
    import numpy as np

    from analysis.kinetostatics.maps import WORST_CASE_WRENCH
    from analysis.kinetostatics.stiffness import (
        cartesian_stiffness,
        complementary_stiffness,
        deflection,
    )
    from analysis.model.kinematics import jacobian
    from analysis.model.robots import load_robot

    _, _, out = run([*campaign, *STIFFNESS_ARGS, "--json"])
    data = json.loads(out)
    robot = load_robot("kr240-2")
    q = np.radians([0, 30, 10, 45, 45, 45])
    K_C = complementary_stiffness(robot, q, WORST_CASE_WRENCH)
    J = jacobian(robot, q)
    K_X = cartesian_stiffness(J, robot.nominal_stiffness, K_C)
    np.testing.assert_allclose(data["K_X"], K_X, rtol=1e-10)
    np.testing.assert_allclose(
        data["deflection_m_rad"], deflection(J, robot.nominal_stiffness, WORST_CASE_WRENCH, K_C),
        rtol=1e-9)


def best_of(pairs: list[tuple[list[str], list[str]]], repeats: int) -> list[dict]:
    """Per (command, baseline): best CPU and wall s of each, runs alternating; the first
    outputs kept. One untimed warm-up run of each first (bytecode, file cache)."""
    for cmd, ref in pairs:
        run(cmd), run(ref)
    best = [{"cpu": [float("inf")] * 2, "wall": [float("inf")] * 2, "out": [None, None]}
            for _ in pairs]
    for _ in range(repeats):
        for b, (cmd, ref) in zip(best, pairs, strict=True):
            for side, c in ((1, ref), (0, cmd)):
                cpu, wall, out = run(c)
                b["cpu"][side] = min(b["cpu"][side], cpu)
                b["wall"][side] = min(b["wall"][side], wall)
                b["out"][side] = b["out"][side] if b["out"][side] is not None else out
    return best


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="runs of each side (best of)")
    args = parser.parse_args()
    from campaign.cli.app import LAZY_COMMANDS

    campaign = campaign_command()
    env_note = "COLUMNS=80 for both sides"
    with tempfile.TemporaryDirectory() as tmp:
        app = [sys.executable, str(minimal_app(Path(tmp) / "minimal_campaign.py"))]
        names = sorted(LAZY_COMMANDS)
        pairs = ([([*campaign, "--help"], [*app, "--help"])]
                 + [([*campaign, n, "--help"], [*app, n, "--help"]) for n in names]
                 + [([*campaign, *STIFFNESS_ARGS], [sys.executable, "-c", STIFFNESS_REFERENCE])])
        best = best_of(pairs, args.repeats)
    top, per_cmd, stiff = best[0], best[1:-1], best[-1]
    check_help(top["out"][0])
    if commands_panel(top["out"][0]) != commands_panel(top["out"][1]):
        raise SystemExit("campaign --help and the minimal app list different commands:\n"
                         + "\n".join(commands_panel(top["out"][0]))
                         + "\n".join(commands_panel(top["out"][1])))
    heavy = {"": heavy_imports(["--help"])} | {n: heavy_imports([n, "--help"]) for n in names}
    bad = {n or "(none)": h for n, h in heavy.items() if h}
    if bad:
        raise SystemExit(f"--help imports heavy libraries: {bad}")
    check_stiffness(campaign)

    def ratio(b):
        return b["cpu"][0] / b["cpu"][1]

    help_ratio, stiff_ratio = ratio(top), ratio(stiff)
    cmd_rows = {n: {"cpu_s": round(b["cpu"][0], 4), "baseline_cpu_s": round(b["cpu"][1], 4),
                    "ratio": round(ratio(b), 3), "heavy_imports": heavy[n]}
                for n, b in zip(names, per_cmd, strict=True)}
    worst = max(cmd_rows, key=lambda n: cmd_rows[n]["ratio"])
    print(f"CPU time, best of {args.repeats} (user + system); command: {' '.join(campaign)}; "
          f"{env_note}")
    print(f"{'case':34s} {'CPU s':>7s} {'baseline CPU s':>15s} {'ratio':>6s}")
    print(f"{'campaign --help':34s} {top['cpu'][0]:7.3f} {top['cpu'][1]:15.3f} "
          f"{help_ratio:6.2f}  (limit {HELP_LIMIT})")
    for n, r in cmd_rows.items():
        print(f"{'campaign ' + n + ' --help':34s} {r['cpu_s']:7.3f} {r['baseline_cpu_s']:15.3f} "
              f"{r['ratio']:6.2f}  heavy imports: {', '.join(r['heavy_imports']) or 'none'}")
    print(f"{'campaign stiffness (one pose)':34s} {stiff['cpu'][0]:7.3f} {stiff['cpu'][1]:15.3f} "
          f"{stiff_ratio:6.2f}  (limit {STIFFNESS_LIMIT})")
    print("outputs checked: --help lists every command module, the same Commands panel as the "
          "minimal app; no --help imports a heavy library; stiffness --json K_X and deflection "
          "match the library")
    load.emit({
        "benchmark": "startup", "repeats": args.repeats,
        "timing": f"CPU time (user + system, getrusage of the child) of a new process per "
                  f"run, best of {args.repeats}, command and baseline alternating, after one "
                  "untimed warm-up run of each",
        "help_command": "campaign --help", "help_cpu_s": round(top["cpu"][0], 4),
        "help_reference": "a one-file typer app with the same commands, help lines and "
                          "--version (nothing else imported), --help; same Commands panel",
        "help_ref_cpu_s": round(top["cpu"][1], 4), "help_ratio": round(help_ratio, 3),
        "help_limit": HELP_LIMIT, "help_within_limit": help_ratio <= HELP_LIMIT,
        "command_help": cmd_rows, "command_help_worst": worst,
        "command_help_worst_ratio": cmd_rows[worst]["ratio"],
        "command_help_max_cpu_s": max(r["cpu_s"] for r in cmd_rows.values()),
        "command_help_heavy_imports": sorted({m for h in heavy.values() for m in h}),
        "stiffness_command": "campaign " + " ".join(STIFFNESS_ARGS),
        "stiffness_cpu_s": round(stiff["cpu"][0], 4),
        "stiffness_reference": f"python -c \"{STIFFNESS_REFERENCE}\"",
        "stiffness_ref_cpu_s": round(stiff["cpu"][1], 4),
        "stiffness_ratio": round(stiff_ratio, 3), "stiffness_limit": STIFFNESS_LIMIT,
        "stiffness_within_limit": stiff_ratio <= STIFFNESS_LIMIT,
    })


if __name__ == "__main__":
    main()
