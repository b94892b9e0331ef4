"""Run the benchmarks, record their JSON lines in results.jsonl, check the targets.

Each ``benchmarks/bench_*.py`` (or the ones named) runs in a subprocess of this
interpreter; its output is shown as it comes, and its last stdout line must be
one JSON object (its figures). For each benchmark one record is appended to
``benchmarks/results/results.jsonl``: the benchmark, the date (UTC), the git
commit (and whether the work tree had changes), the run mode (full: the
benchmark's own defaults; quick: the small sizes of :data:`QUICK`; custom:
options given with ``--args``), the machine (CPU count and model, load average
before and after), the Python and numpy versions, the benchmark's wall time,
the target statuses and the figures. The targets are those of
:mod:`targets`.

Exit status: 0 when every benchmark ran and no target was missed; 1 when a
target was missed (the record is kept); 2 when a benchmark failed or its last
line was not one JSON object (no record for it). A target a run did not measure
(e.g. the 1e6-test import in a quick run) is reported, not failed.

Run everything and regenerate the table of docs/benchmarks.md::

    python benchmarks/run_all.py --table

Options: names to select benchmarks (``maps planner``), ``--quick`` for small
sizes, ``--args NAME="--sizes 1000"`` to pass options to one benchmark,
``--results FILE``, ``--table`` (or its old name ``--readme``) to rewrite the table of
docs/benchmarks.md afterwards.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import shlex
import subprocess
import sys
import time
from importlib import metadata
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

from targets import MISSED, NOT_MEASURED, check_all  # noqa: E402

RESULTS = HERE / "results" / "results.jsonl"

#: small sizes for ``--quick``: a check that everything runs, not figures for the README
QUICK: dict[str, list[str]] = {
    "maps": ["--sample", "300", "--repeat", "1"],
    "identification": ["--trials", "10000", "--loop", "500", "--study-trials", "100000",
                       "--repeat", "1"],
    "large_import": ["--sizes", "2000", "--repeat", "1"],
    "planner": ["--baseline-candidates", "1000", "--sizes", "2000", "10000", "--repeat", "1"],
    "fake_campaign": ["--scales", "200", "400", "800", "--repeat", "2"],
    "compensate": ["--points", "1000", "--sample", "50"],
    "place": ["--placements", "4", "--sample", "50", "--repeat", "2"],
    "startup": ["--repeats", "2"],
    "csv_io": ["--sizes", "2000", "--write-tests", "2000", "--repeat", "1"],
    "gui_sensitivity": ["--repeat", "1"],
    "acquire_state": ["--repeat", "1", "--polls", "5"],
    "ledger": ["--robots", "200", "--repeat", "2"],
}


def discover(bench_dir: Path) -> dict[str, Path]:
    """{name: script} of every bench_*.py, name without ``bench_`` and ``.py``."""
    return {p.stem.removeprefix("bench_"): p for p in sorted(bench_dir.glob("bench_*.py"))}


def git_commit(cwd: Path) -> tuple[str | None, bool | None]:
    """(HEAD commit, whether tracked files other than the results and the table's page differ
    from it); (None, None) outside git."""
    try:
        head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True,
                              text=True, check=True).stdout.strip()
        status = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no", "--",
                                 ".", ":!benchmarks/results", ":!docs/benchmarks.md"],
                                cwd=cwd, capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None, None
    return head, bool(status.strip())


def cpu_model() -> str | None:
    """The CPU's model name from /proc/cpuinfo (Linux), else platform.processor()."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or None


def load_average() -> list[float]:
    """1, 5 and 15 min load averages."""
    return [round(v, 2) for v in os.getloadavg()]


def run_one(script: Path, args: list[str], timeout: float | None) -> tuple[int, str, float]:
    """(exit code, last non-empty stdout line, wall s); the output is echoed as it comes."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, str(script), *args], cwd=ROOT,
                            stdout=subprocess.PIPE, text=True, bufsize=1)
    last = ""
    try:
        for line in proc.stdout:
            sys.stdout.write("  | " + line)
            sys.stdout.flush()
            if line.strip():
                last = line.strip()
        code = proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
        code = -9
    return code, last, time.perf_counter() - t0


def parse_figures(line: str) -> dict | None:
    """The JSON object of a benchmark's last line, or None if it is not one."""
    try:
        obj = json.loads(line)
    except ValueError:
        return None
    return obj if isinstance(obj, dict) else None


def parse_extra(items: list[str], names: dict[str, Path]) -> dict[str, list[str]]:
    """{name: options} from ``NAME=OPTIONS`` items; an unknown name stops the run."""
    out: dict[str, list[str]] = {}
    for item in items:
        name, sep, opts = item.partition("=")
        if not sep or name not in names:
            raise SystemExit(f"--args {item!r}: expected NAME=OPTIONS with NAME one of "
                             f"{', '.join(names)}")
        out.setdefault(name, []).extend(shlex.split(opts))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("names", nargs="*", help="benchmarks to run (default: all)")
    parser.add_argument("--quick", action="store_true", help="small sizes (see QUICK)")
    parser.add_argument("--args", action="append", default=[], metavar="NAME=OPTIONS",
                        help="options for one benchmark, e.g. large_import='--sizes 10000'")
    parser.add_argument("--results", type=Path, default=RESULTS, help="results.jsonl to append to")
    parser.add_argument("--bench-dir", type=Path, default=HERE, help=argparse.SUPPRESS)
    parser.add_argument("--timeout", type=float, default=None, help="s per benchmark")
    parser.add_argument("--table", "--readme", action="store_true", dest="table",
                        help="regenerate the benchmark table of docs/benchmarks.md from the "
                             "results")
    args = parser.parse_args(argv)

    scripts = discover(args.bench_dir)
    unknown = [n for n in args.names if n not in scripts]
    if unknown:
        raise SystemExit(f"no benchmark named {', '.join(unknown)} in {args.bench_dir} "
                         f"(have: {', '.join(scripts)})")
    extra = parse_extra(args.args, scripts)
    selected = args.names or list(scripts)
    commit, dirty = git_commit(ROOT)
    machine = {"cpu_count": os.cpu_count(), "cpu_model": cpu_model(),
               "platform": platform.platform()}
    versions = {"python": platform.python_version(), "numpy": metadata.version("numpy")}
    failed, missed = [], []
    args.results.parent.mkdir(parents=True, exist_ok=True)
    for name in selected:
        opts = (QUICK.get(name, []) if args.quick else []) + extra.get(name, [])
        mode = "custom" if name in extra else "quick" if args.quick else "full"
        print(f"== {name}: {scripts[name].name} {' '.join(opts)} ({mode})", flush=True)
        load_before = load_average()
        date = dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
        code, last, wall = run_one(scripts[name], opts, args.timeout)
        load_after = load_average()
        figures = parse_figures(last)
        if code != 0 or figures is None:
            why = (f"exit code {code}" if code != 0
                   else f"last line is not one JSON object: {last[:120]!r}")
            print(f"== {name}: FAILED ({why}); nothing recorded", flush=True)
            failed.append(name)
            continue
        checks = check_all(name, figures)
        record = {
            "benchmark": name, "script": f"benchmarks/{scripts[name].name}", "date_utc": date,
            "git_commit": commit, "git_dirty": dirty, "mode": mode, "args": opts,
            "machine": {**machine, "load_average_before": load_before,
                        "load_average_after": load_after},
            **versions, "wall_s": round(wall, 2),
            "targets": {t.text(): status for t, status, _ in checks},
            "figures": figures,
        }
        with open(args.results, "a") as fh:
            fh.write(json.dumps(record) + "\n")
        for t, status, value in checks:
            shown = "-" if value is None else f"{value:g}"
            extra_note = f" (needs {t.requires})" if status == NOT_MEASURED else ""
            print(f"   target {t.text()}: {shown} -> {status}{extra_note}")
        if any(status == MISSED for _, status, _ in checks):
            missed.append(name)
        print(f"== {name}: recorded in {args.results} ({wall:.0f} s wall; load average "
              f"{load_before[0]:.1f} -> {load_after[0]:.1f})", flush=True)
    if args.table:
        from readme_table import PAGE, update_page

        changed = update_page(PAGE, args.results)
        print(f"{PAGE.relative_to(ROOT)} table {'regenerated' if changed else 'unchanged'} "
              f"from {args.results}")
    if failed:
        print(f"FAILED: {', '.join(failed)}")
    if missed:
        print(f"targets missed: {', '.join(missed)}")
    return 2 if failed else 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
