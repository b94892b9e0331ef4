"""Benchmark: reading a tests CSV into TestArrays and writing residuals.csv, at large sizes.

Read: for each size N (default 1e5 and 1e6 tests; the files of :mod:`_large_csv`,
kept and reused with ``--data DIR``) three fresh processes, each started from a
small launcher (CPU user + system and peak RSS of that one child from
``os.wait4``), import what ``campaign analyze`` imports (``campaign.cli.app``, the
identification, pyarrow), then

* ``arrow``: read the file with ``read_test_arrays`` (Arrow's streaming CSV reader
  straight into the arrays);
* ``table``: read it with ``to_arrays(read_csv(...))`` (pandas' C reader, the tidy SI
  table, then the arrays): the route it replaces, the same work;
* ``imports``: nothing more (the imports' share of the peak RSS).

Outputs compared: each reading process prints the SHA-256 of its arrays (q, w, d,
measured, line and the pose labels); the two must agree.

Write: the residual table of a file of ``--write-tests`` tests (default 1e5: 6e5
rows), with deterministic stand-ins for the predicted displacements,
sigmas and studentized residuals, written as residuals.csv in this process by
``result.write_table`` (:mod:`analysis.identification.io.table_csv`) and by pandas'
``DataFrame.to_csv`` block by block (the text residuals.csv must have, the same
bytes); CPU time (``time.process_time``), best of ``--repeat``; the files'
bytes compared.

Run: ``python benchmarks/bench_csv_io.py [--sizes 100000 1000000] [--data DIR]
[--write-tests 100000] [--repeat 3]``. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _launcher import Launcher  # noqa: E402
from _load import LoadWindow

#: the timed reading process: argv mode (arrow, table, imports) and the CSV file
READER = r"""
import hashlib, json, sys
import numpy as np
import pyarrow.csv  # noqa: F401
import campaign.cli.app  # noqa: F401
import analysis.identification.estimate  # noqa: F401
import analysis.identification.result  # noqa: F401
from analysis.identification.io.measurements import read_csv, read_test_arrays, to_arrays
mode, path = sys.argv[1], sys.argv[2]
if mode == "imports":
    print(json.dumps({}))
    sys.exit(0)
tests = read_test_arrays(path) if mode == "arrow" else to_arrays(read_csv(path))
digest = hashlib.sha256()  # column by column: no copy of the arrays adds to the peak
for a in (tests.q, tests.w, tests.d, tests.measured, tests.line[:, None]):
    for j in range(a.shape[1]):
        digest.update(np.ascontiguousarray(a[:, j]))
for s in range(0, tests.m, 100_000):
    digest.update("\n".join(tests.pose[s:s + 100_000].tolist()).encode())
print(json.dumps({"m": tests.m, "sha256": digest.hexdigest()}))
"""


def residual_rows(csv: Path, n: int):
    """A ResidualRows of the first n tests of ``csv`` with deterministic stand-ins."""
    from analysis.identification.io.csv_reader import read_test_arrays
    from analysis.identification.io.residual_rows import ResidualRows

    tests = read_test_arrays(csv)
    tests = tests.subset(np.arange(min(n, tests.m)))
    rng = np.random.default_rng(0)
    predicted = np.where(tests.measured, tests.d * (1 + 1e-2 * rng.normal(size=tests.d.shape)),
                         np.nan)
    sigma = np.where(np.arange(6) < 3, 2e-5, 1e-5) * (1 + rng.random(tests.d.shape))
    t = (tests.d - predicted) / sigma
    t[::97, 2] = np.nan  # a few cells not finite: empty in the file
    return ResidualRows(tests, predicted, sigma, t, np.abs(np.nan_to_num(t)) > 3)


def time_write(rows, path: Path, how: str, repeat: int) -> float:
    from analysis.identification.io.results_json import write_table

    best = np.inf
    for _ in range(repeat):
        t0 = time.process_time()
        if how == "table_csv":
            write_table(rows, path)
        else:
            with open(path, "w", newline="") as fh:
                for k, frame in enumerate(rows.frames()):
                    frame.to_csv(fh, index=False, header=k == 0)
        best = min(best, time.process_time() - t0)
    return best


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[100_000, 1_000_000])
    parser.add_argument("--data", type=Path, default=None,
                        help="directory for the generated CSV files (kept; reused if present)")
    parser.add_argument("--write-tests", type=int, default=100_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    launcher = Launcher()
    from _large_csv import write_csv

    figures: dict = {"benchmark": "csv_io", "read": {}, "timing": "CPU user+sys (wait4) and "
                     "peak RSS of fresh processes; writing: process_time, best of repeat",
                     "baseline": "read: to_arrays(read_csv) (pandas C reader, tidy table); "
                     "write: pandas DataFrame.to_csv block by block (same bytes)"}
    with tempfile.TemporaryDirectory() as tmp:
        data = args.data or Path(tmp)
        data.mkdir(parents=True, exist_ok=True)
        for n in args.sizes:
            csv = data / f"tests_{n}.csv"
            if not csv.exists():
                write_csv(csv, n)
            runs = {mode: launcher.run([sys.executable, "-c", READER, mode, csv])
                    for mode in ("imports", "arrow", "table")}
            got = {mode: json.loads(runs[mode]["stdout"].strip().splitlines()[-1])
                   for mode in ("arrow", "table")}
            row = {mode: {"cpu_s": round(r["cpu_s"], 3), "peak_rss_MB": round(r["peak_rss_MB"])}
                   for mode, r in runs.items()}
            row["same_arrays"] = got["arrow"]["sha256"] == got["table"]["sha256"]
            row["ratio_peak_above_imports"] = round(
                (runs["table"]["peak_rss_MB"] - runs["imports"]["peak_rss_MB"])
                / (runs["arrow"]["peak_rss_MB"] - runs["imports"]["peak_rss_MB"]), 2)
            row["ratio_cpu_read"] = round(
                (runs["table"]["cpu_s"] - runs["imports"]["cpu_s"])
                / (runs["arrow"]["cpu_s"] - runs["imports"]["cpu_s"]), 2)
            figures["read"][str(n)] = row
            print(f"read N={n}: {json.dumps(row)}", flush=True)
        csv = data / f"tests_{args.write_tests}.csv"
        if not csv.exists():
            write_csv(csv, args.write_tests)
        rows = residual_rows(csv, args.write_tests)
        paths = {how: Path(tmp) / f"residuals_{how}.csv" for how in ("table_csv", "pandas")}
        cpu = {how: time_write(rows, paths[how], how, args.repeat) for how in paths}
        same = paths["table_csv"].read_bytes() == paths["pandas"].read_bytes()
        figures["write"] = {
            "tests": rows.tests.m, "rows": rows.n_rows,
            "file_MB": round(paths["pandas"].stat().st_size / 2**20, 1),
            "table_csv_cpu_s": round(cpu["table_csv"], 3), "pandas_cpu_s": round(cpu["pandas"], 3),
            "ratio_cpu": round(cpu["pandas"] / cpu["table_csv"], 2), "same_bytes": same,
            "sha256": hashlib.sha256(paths["pandas"].read_bytes()).hexdigest()[:16]}
        print(f"write: {json.dumps(figures['write'])}", flush=True)
    load.emit(figures)


if __name__ == "__main__":
    main()
