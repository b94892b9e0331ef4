"""Benchmark of the command line's start-up: CPU time of two commands against bare imports.

Run: ``python benchmarks/bench_startup.py [--repeats N]``. Each command runs in
a new process; its CPU time (user + system, from ``getrusage(RUSAGE_CHILDREN)``)
is compared with that of a Python process that only imports the libraries the
command cannot do without, timed the same way in the same run:

* ``campaign --help`` against ``python -c "import numpy, typer, rich"``
  (limit 2x),
* ``campaign stiffness --robot kr240-2 --q 0,30,10,45,45,45`` (one pose)
  against ``python -c "import numpy, typer, rich, pinocchio"`` (limit 2.5x).

Commands and references alternate, best of N each, so that load from other
jobs on the machine hits both sides alike. The outputs are checked: ``--help``
must list every command module, and the stiffness command's ``--json`` output
(run once, untimed) must match the library's K_X and deflection. The last line
printed is one JSON object of the figures.
"""

from __future__ import annotations

import argparse
import json
import pkgutil
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

STIFFNESS_ARGS = ["stiffness", "--robot", "kr240-2", "--q", "0,30,10,45,45,45"]
CASES = (
    # (name, campaign arguments, reference imports, limit of the CPU ratio)
    ("campaign --help", ["--help"], "import numpy, typer, rich", 2.0),
    ("campaign stiffness (one pose)", STIFFNESS_ARGS, "import numpy, typer, rich, pinocchio",
     2.5),
)


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
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
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
        data["deflection"], deflection(J, robot.nominal_stiffness, WORST_CASE_WRENCH, K_C),
        rtol=1e-9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7, help="runs of each side (best of)")
    args = parser.parse_args()
    campaign = campaign_command()
    rows = []
    for name, cargs, imports, limit in CASES:
        ref_cmd = [sys.executable, "-c", imports]
        cmd = [*campaign, *cargs]
        run(cmd)  # warm the file cache (bytecode, shared libraries) before timing
        best = {"cmd": (float("inf"), float("inf")), "ref": (float("inf"), float("inf"))}
        for _ in range(args.repeats):
            for side, c in (("ref", ref_cmd), ("cmd", cmd)):
                cpu, wall, out = run(c)
                best[side] = (min(best[side][0], cpu), min(best[side][1], wall))
                if side == "cmd" and cargs == ["--help"]:
                    check_help(out)
        rows.append({"case": name, "command": " ".join(["campaign", *cargs]),
                     "cpu_s": best["cmd"][0], "wall_s": best["cmd"][1],
                     "reference": f"python -c \"{imports}\"", "ref_cpu_s": best["ref"][0],
                     "ref_wall_s": best["ref"][1], "ratio": best["cmd"][0] / best["ref"][0],
                     "limit": limit})
    check_stiffness(campaign)
    print(f"CPU time, best of {args.repeats} (user + system); command: {' '.join(campaign)}")
    print(f"{'case':32s} {'CPU s':>7s} {'wall s':>7s} {'reference CPU s':>16s} "
          f"{'ratio':>6s} {'limit':>6s}")
    for r in rows:
        verdict = "ok" if r["ratio"] <= r["limit"] else "OVER"
        print(f"{r['case']:32s} {r['cpu_s']:7.3f} {r['wall_s']:7.3f} {r['ref_cpu_s']:16.3f} "
              f"{r['ratio']:6.2f} {r['limit']:6.1f}  {verdict}")
    print("references: " + "; ".join(f"{r['case']}: {r['reference']}" for r in rows))
    print("outputs checked: --help lists every command module; stiffness --json K_X and "
          "deflection match the library")
    figures = {"benchmark": "startup", "repeats": args.repeats,
               "timing": f"CPU time (user + system, getrusage of the child) of a new "
                         f"process per run, best of {args.repeats}, command and reference "
                         "alternating, after one untimed warm-up run"}
    for key, r in zip(("help", "stiffness"), rows, strict=True):
        figures.update({f"{key}_cpu_s": round(r["cpu_s"], 4),
                        f"{key}_ref_cpu_s": round(r["ref_cpu_s"], 4),
                        f"{key}_ratio": round(r["ratio"], 3), f"{key}_limit": r["limit"],
                        f"{key}_within_limit": r["ratio"] <= r["limit"],
                        f"{key}_command": r["command"],
                        f"{key}_reference": r["reference"]})
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
