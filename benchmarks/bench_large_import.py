"""Benchmark: ``campaign analyze --measurements`` on large CSV imports, and two small analyses.

For each size N (default 1e4, 1e5, 1e6 tests) a CSV of N simulated tests is
written (KR240-2, nominal stiffness, 10 tests per pose, exact equilibrium plus
the default noise model's noise: :mod:`_large_csv`), then
``campaign analyze --measurements FILE --robot kr240-2 --no-report
--accept-misfit`` runs in a subprocess for each method (ols, exact), with the
leave-one-pose-out validation (N / 10 poses). CPU (user + system) and peak RSS
of that subprocess come from ``os.wait4`` (the rusage of that one child, what
``resource.getrusage(RUSAGE_CHILDREN)`` reports for a single child), started
from a small launcher process (a child forked from this large process would
count this process's pages in its peak RSS), so
start-up, CSV reading, identification, validation and writing the results are
all counted. ``--accept-misfit``: OLS is biased by the linearisation on data
from the exact equilibrium, and its chi-square test refuses it at large N
(correctly); the benchmark times it anyway.

Checked outputs: the raw OLS compliances of results.json (``linearisation_bias``:
before the correction of the linearisation bias) against an independent
reference (numpy.linalg.lstsq on the dense stacked design built from the CSV
read by pandas, at every N), the OLS standard errors against the dense sandwich
G Sigma G^T (N <= 1e4), and the exact fit's k against the simulated truth
(within 6 standard errors).

Also timed the same way: ``campaign analyze`` on 1000 tests with validation
(ols and exact, no report), and ``campaign analyze`` of the demo run with its
report, against ``python -c "import numpy, pandas, matplotlib.pyplot,
pinocchio"`` (best of ``--repeat`` for each, after one untimed run of the analysis;
the machine may be shared, so each figure is the best of the repeats). These two run
with Python's bytecode cache on, in a temporary directory (``PYTHONPYCACHEPREFIX``,
``PYTHONDONTWRITEBYTECODE`` removed), as an installed copy runs: the imports'
packages come precompiled by pip, while with ``PYTHONDONTWRITEBYTECODE`` set (the
development machine sets it) the command compiled its ~140 modules of this project
from source on every run, 0.3-0.4 s of its ~3.4 s of CPU (issue 36, measured on the
demo at 300 px per inch), a cost of that environment, not of the analysis.

Run: ``python benchmarks/bench_large_import.py [--sizes 10000 100000 1000000]
[--data DIR] [--repeat 3] [--demo-only]``; ``--demo-only`` times only the demo
analysis against the imports. The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _launcher import Launcher  # noqa: E402
from _load import LoadWindow

BIN = Path(sys.executable).parent
CAMPAIGN = [str(BIN / "campaign")] if (BIN / "campaign").exists() else [
    sys.executable, "-m", "campaign"]


def best(launcher: Launcher, args: list[str], repeat: int) -> dict:
    runs = [launcher.run(args) for _ in range(repeat)]
    out = min(runs, key=lambda r: r["cpu_s"])
    out["cpu_s_all"] = [round(r["cpu_s"], 3) for r in runs]
    return out


def reference_ols(csv: Path, dense_se: bool) -> tuple[np.ndarray, np.ndarray | None]:
    """OLS compliances (6,) by numpy.linalg.lstsq on the dense stacked design, corrected for
    the wrench errors-in-variables as the analysis does; with ``dense_se`` also their
    standard errors from the dense G Sigma G^T (uncorrected: the correction changes them by
    ~1e-4 relative)."""
    import pandas as pd

    from analysis.identification.estimators.linear_model import design_block
    from analysis.identification.noise import NoiseModel, residual_covariance
    from analysis.model.kinematics import jacobian
    from analysis.model.robots import load_robot

    robot = load_robot("kr240-2")
    frame = pd.read_csv(csv)
    q = np.radians(frame[[f"q{i}_deg" for i in range(1, 7)]].to_numpy(float))
    w = frame[["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]].to_numpy(float)
    d = 1e-3 * frame[["dx_mm", "dy_mm", "dz_mm", "rx_mrad", "ry_mrad", "rz_mrad"]].to_numpy(
        float)
    A = np.concatenate([design_block(jacobian(robot, q[s:s + 50_000]), w[s:s + 50_000])
                        for s in range(0, len(q), 50_000)])
    x = np.linalg.lstsq(A.reshape(-1, 6), d.reshape(-1), rcond=None)[0]
    # the wrench errors-in-variables correction of the analysis, written out here from its
    # formula (not the package's function): (A^T A - S) x_c = A^T d, with
    # S = sum_tests (J^T J) o (J^T Sigma_w J) and Sigma_w diagonal (the default F/T figures)
    nm = NoiseModel()
    sw = np.array([nm.force_sigma] * 3 + [nm.moment_sigma] * 3) ** 2
    S = np.zeros((6, 6))
    for s in range(0, len(q), 50_000):
        Jb = jacobian(robot, q[s:s + 50_000])
        S += np.einsum("mrj,mrk,msj,s,msk->jk", Jb, Jb, Jb, sw, Jb, optimize=True)
    Af = A.reshape(-1, 6)
    N = Af.T @ Af
    M = np.linalg.inv(np.eye(6) - np.linalg.solve(N, S))  # x_c = M x, cov_c = M cov M^T
    x = M @ x
    if not dense_se:
        return x, None
    G = np.linalg.pinv(A.reshape(-1, 6))  # (6, 6m)
    J = jacobian(robot, q)
    C = np.einsum("mij,j,mkj->mik", J, x, J)
    cov = residual_covariance(NoiseModel(), C)  # (m, 6, 6)
    GS = np.einsum("pmi,mij->pmj", G.reshape(6, -1, 6), cov).reshape(6, -1)
    return x, np.sqrt(np.diag(M @ (GS @ G.T) @ M.T))


def analyze_csv(csv: Path, out: Path, method: str, extra: tuple[str, ...] = ()) -> list[str]:
    return [*CAMPAIGN, "analyze", "--measurements", str(csv), "--robot", "kr240-2",
            "--out", str(out), "--force", "--method", method, "--no-report", "--accept-misfit",
            *extra]


def main() -> None:
    load = LoadWindow()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    parser.add_argument("--methods", nargs="+", default=["ols", "exact"])
    parser.add_argument("--data", type=Path, default=None,
                        help="directory for the generated CSV files (kept; reused if present)")
    parser.add_argument("--repeat", type=int, default=3, help="repeats of the small analyses")
    parser.add_argument("--demo-only", action="store_true",
                        help="only the demo analysis with its report against the imports")
    args = parser.parse_args()
    launcher = Launcher()  # before the large imports and arrays of this process
    from _large_csv import write_csv

    from analysis.model.robots import load_robot

    k_true = load_robot("kr240-2").nominal_stiffness
    figures: dict = {"large": {}, "small": {}}
    with tempfile.TemporaryDirectory() as tmp:
        data = args.data or Path(tmp)
        data.mkdir(parents=True, exist_ok=True)
        for n in [] if args.demo_only else args.sizes:
            csv = data / f"tests_{n}.csv"
            if not csv.exists():
                write_csv(csv, n)
            row: dict = {}
            for method in args.methods:
                out = Path(tmp) / f"out_{n}_{method}"
                r = launcher.run(analyze_csv(csv, out, method))
                res = json.loads((out / "results.json").read_text())
                x = np.array(res["joint_compliance_rad_per_Nm"], float)
                se_k = np.array(res["standard_error_Nm_per_rad"], float)
                k = np.array(res["joint_stiffness_Nm_per_rad"], float)
                r["n_poses"] = res["n_poses"]
                r["residuals_listed"] = res.get("residuals_listed")
                r["validation_listed"] = res.get("validation_listed")
                r["results_json_MB"] = (out / "results.json").stat().st_size / 2**20
                if method == "ols":
                    # the least-squares solution itself: the raw OLS estimate, before the
                    # linearisation-bias correction (results.json linearisation_bias)
                    raw = res["linearisation_bias"]
                    x = 1.0 / np.array(raw["raw_joint_stiffness_Nm_per_rad"], float)
                    se_k = np.array(raw["raw_standard_error_Nm_per_rad"], float)
                    x_ref, se_ref = reference_ols(csv, dense_se=n <= 10_000)
                    r["x_rel_diff_vs_lstsq"] = float(np.max(np.abs(x / x_ref - 1)))
                    if se_ref is not None:
                        se_x = se_k * x**2  # se(k) = se(x) / x^2
                        r["se_rel_diff_vs_dense_sandwich"] = float(np.max(np.abs(
                            se_x / se_ref - 1)))
                else:
                    r["max_abs_k_error_in_se"] = float(np.max(np.abs(k - k_true) / se_k))
                row[method] = r
                print(f"N={n:>8} {method:5s}: {r['cpu_s']:7.1f} s CPU, "
                      f"{r['peak_rss_MB']:7.0f} MB peak RSS, {r['wall_s']:6.1f} s wall, "
                      f"{r['n_poses']} poses; " + ", ".join(
                          f"{key} {val:.2g}" for key, val in r.items()
                          if key.startswith(("x_rel", "se_rel", "max_abs"))), flush=True)
            figures["large"][str(n)] = row

        # small analyses: 1000 tests with validation; the demo run with its report
        csv = data / "tests_1000.csv"
        if not csv.exists() and not args.demo_only:
            write_csv(csv, 1000)
        for method in () if args.demo_only else ("ols", "exact"):
            r = best(launcher, analyze_csv(csv, Path(tmp) / f"small_{method}", method), args.repeat)
            figures["small"][f"analyze_1000_tests_validation_{method}"] = r
            print(f"1000 tests, validation, {method}: {r['cpu_s']:.2f} s CPU (best of "
                  f"{args.repeat})", flush=True)
        demo = Path(tmp) / "demo"
        subprocess.run([*CAMPAIGN, "demo", "--out", str(demo), "--quiet", "--no-report"],
                       check=True, capture_output=True)
        # bytecode cached as an installed copy has it (see the module's docstring)
        cached = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        cached["PYTHONPYCACHEPREFIX"] = str(Path(tmp) / "pycache")
        demo_launcher = Launcher(cached)
        analyze_demo = [*CAMPAIGN, "analyze", str(demo / "run"), "--out", str(demo / "an"),
                        "--force"]
        demo_launcher.run(analyze_demo)  # untimed: fills the bytecode cache
        r = best(demo_launcher, analyze_demo, args.repeat)
        base = best(demo_launcher, [sys.executable, "-c",
                                    "import numpy, pandas, matplotlib.pyplot, pinocchio"],
                    args.repeat)
        demo_launcher.close()
        figures["small"]["demo_analyze_with_report"] = r
        figures["small"]["import_numpy_pandas_pyplot_pinocchio"] = base
        figures["small"]["demo_analyze_over_imports"] = r["cpu_s"] / base["cpu_s"]
        figures["small"]["demo_bytecode"] = ("cached (PYTHONPYCACHEPREFIX in a temporary "
                                             "directory, after one untimed run)")
        print(f"demo analysis with report: {r['cpu_s']:.2f} s CPU; imports alone "
              f"{base['cpu_s']:.2f} s; ratio {r['cpu_s'] / base['cpu_s']:.1f} (best of "
              f"{args.repeat} each)", flush=True)
    load.emit({"benchmark": "large_import", "machine_note": "2 shared cores",
                      "baseline": 'python -c "import numpy, pandas, matplotlib.pyplot, '
                                  'pinocchio"',
                      "timing": "CPU (user + sys) and peak RSS of each command's process "
                                "(os.wait4), started from a small launcher process; the "
                                f"large imports one run each, the small analyses and the "
                                f"imports best of {args.repeat}",
                      **figures})


if __name__ == "__main__":
    main()
