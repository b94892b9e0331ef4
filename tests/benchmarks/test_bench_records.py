"""The benchmark records and the table of docs/benchmarks.md generated from them (no
benchmark is run: the runner is exercised on tiny stand-in scripts)."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benchmarks"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


table = _load("readme_table")
targets = _load("targets")


def record(name: str, figures: dict, mode: str = "full", load=(1.5, 2.5), date="2026-01-01"):
    return {"benchmark": name, "script": f"benchmarks/bench_{name}.py", "date_utc": date,
            "git_commit": "0123456789abcdef" * 2 + "01234567", "git_dirty": False,
            "mode": mode, "args": [] if mode == "full" else ["--small"],
            "machine": {"cpu_count": 2, "cpu_model": "Test CPU", "platform": "test",
                        "load_average_before": [load[0], 1.0, 1.0],
                        "load_average_after": [load[1], 1.0, 1.0]},
            "python": "3.11.0", "numpy": "2.0.0", "wall_s": 1.0, "figures": figures}


MAPS = {"benchmark": "maps", "robot": "KR240-2", "grid_step_deg": 0.5, "threads": 1,
        "poses": 161443, "loop_sample": 3000, "repeat": 3, "batched_cpu_us_per_pose": 2.25,
        "batched_wall_us_per_pose": 2.5, "loop_cpu_us_per_pose": 131.625,
        "loop_wall_us_per_pose": 140.0, "ratio_cpu": 58.5, "ratio_wall": 56.0,
        "threaded_wall_us_per_pose": 4.75, "cpus": 2,
        "max_rel_diff": {"inv_kappa_F": 3e-12, "v_p": 4e-11, "v_r": 2e-13},
        "baseline": "per-pose Pinocchio loop", "timing": "CPU time, best of 3"}
PLANNER = {"benchmark": "planner", "baseline_candidates": 2000, "repeat": 2,
           "batched_cpu_us_per_candidate": 20.0, "loop_cpu_us_per_candidate": 1430.0,
           "ratio_cpu": 71.5, "ratio_wall": 70.0,
           "batched_cpu_us_per_candidate_at": {"10000": 16.75, "100000": 31.5},
           "same_design": True, "load_cases": 4, "design_tests": 5,
           "baseline": "same algorithm per candidate", "timing": "CPU time, best of 2"}
LARGE_QUICK = {"benchmark": "large_import", "baseline": "python -c imports", "timing": "wait4",
               "large": {"2000": {"ols": {"cpu_s": 1.25, "peak_rss_MB": 210.5, "n_poses": 200,
                                          "x_rel_diff_vs_lstsq": 3e-15}}},
               "small": {"analyze_1000_tests_validation_ols": {"cpu_s": 1.875},
                         "analyze_1000_tests_validation_exact": {"cpu_s": 2.125},
                         "demo_analyze_with_report": {"cpu_s": 3.25},
                         "import_numpy_pandas_pyplot_pinocchio": {"cpu_s": 1.0},
                         "demo_analyze_over_imports": 3.25}}


def row_of(text: str, script: str) -> str:
    rows = [line for line in text.splitlines() if line.startswith(f"| `{script}`")]
    assert len(rows) == 1, rows
    return rows[0]


def test_table_shows_the_recorded_numbers_and_marks_missed_targets(tmp_path):
    quicker = dict(MAPS, batched_cpu_us_per_pose=9.75, ratio_cpu=12.5)
    lines = [record("maps", MAPS, load=(1.5, 2.5)),
             record("maps", quicker, mode="quick", date="2026-02-01"),  # newer, but quick
             record("planner", PLANNER, load=(0.25, 0.75)),
             record("large_import", LARGE_QUICK, mode="quick")]
    path = tmp_path / "results.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in lines))
    text = table.render(table.read_records(path))

    maps = row_of(text, "benchmarks/bench_maps.py")
    # the full run is preferred to a newer quick one
    for shown in ("161 443 poses", "2.25 us CPU/pose", "132 us CPU/pose on 3 000", "58.5x CPU",
                  "4.75 us wall/pose", "v_p 4.0e-11", "load 1.5 -> 2.5", "full run"):
        assert shown in maps, shown
    assert "9.75" not in maps
    # 2.25 us meets issue 13's 2.5 us, not issue 36's 1 us
    assert maps.count(", met") == 2 and maps.count("**NOT MET**") == 1
    assert "us CPU/pose <= 1 (issue 36: single-threaded, 0.5 deg KR240-2 map; then 0.8): " \
        "2.25, **NOT MET**" in maps

    planner = row_of(text, "benchmarks/bench_planner.py")
    # 31.5 us at 1e5 misses the 30 us target; 31.5 / 16.75 ... / 20 at 2000 (smallest): 1.575
    assert "us CPU/candidate at 1e5 <= 30 (issue 13): 31.5, **NOT MET**" in planner
    assert ": 1.57, **NOT MET**" in planner or ": 1.58, **NOT MET**" in planner
    assert "16.8 at 10 000; 31.5 at 100 000" in planner and "71.5x CPU" in planner
    assert "load 0.25 -> 0.75" in planner

    large = row_of(text, "benchmarks/bench_large_import.py")
    assert "**quick run** (--small)" in large
    assert "N=2 000 (200 poses): ols 1.25 s CPU / 210 MB" in large
    assert "demo 3.25x the imports" in large
    assert "demo analysis with report / imports, CPU <= 3" in large and "3.25, **NOT MET**" in large
    assert "1.88, met" in large and "2.12, met" in large
    # the 1e6 figures were not measured: said so, not counted as met
    assert large.count("not measured (needs --sizes including 1000000)") == 4
    assert "Test CPU, 2 CPUs, Python 3.11.0, numpy 2.0.0" in text


def test_target_statuses_from_figures():
    (kernel, ratio, kernel_36) = targets.targets_of("maps")
    assert kernel_36.check(MAPS) == (targets.MISSED, 2.25)
    assert kernel_36.check(dict(MAPS, batched_cpu_us_per_pose=1.0)) == (targets.MET, 1.0)
    assert kernel.check(MAPS) == (targets.MET, 2.25)
    assert kernel.check(dict(MAPS, batched_cpu_us_per_pose=2.5)) == (targets.MET, 2.5)
    assert kernel.check(dict(MAPS, batched_cpu_us_per_pose=2.51))[0] == targets.MISSED
    assert kernel.check(dict(MAPS, grid_step_deg=1.0)) == (targets.NOT_MEASURED, None)
    assert ratio.check(dict(MAPS, ratio_cpu=7.9))[0] == targets.MISSED
    assert ratio.check(dict(MAPS, ratio_cpu=8.0))[0] == targets.MET
    assert ratio.check({}) == (targets.NOT_MEASURED, None)
    place = targets.targets_of("place")
    figures = {"commands": {"readme": {"estimate_ratio": 1.25, "system_over_wall": 0.0625,
                                       "evaluations_per_s": 7e5, "probe_per_process_per_s": 4e5}}}
    assert [t.check(figures) for t in place] == [
        (targets.MET, 1.25), (targets.MET, 0.0625), (targets.MISSED, 0.875),
        *[(targets.NOT_MEASURED, None)] * 3]


def test_every_benchmark_has_a_row_description_and_every_target_a_benchmark():
    scripts = {p.stem.removeprefix("bench_") for p in BENCH.glob("bench_*.py")}
    assert set(table.ROWS) == scripts
    assert {t.benchmark for t in targets.TARGETS} <= scripts


def test_the_benchmark_page_table_is_the_one_made_from_the_committed_results():
    results = BENCH / "results" / "results.jsonl"
    assert table.PAGE == ROOT / "docs" / "benchmarks.md"
    page = table.PAGE.read_text()
    expected = table.replace_block(page, table.render(table.read_records(results)))
    assert page == expected, ("docs/benchmarks.md's table is stale: run "
                              "python benchmarks/readme_table.py")
    assert table.START not in (ROOT / "README.md").read_text()


def test_a_damaged_results_line_is_named(tmp_path):
    path = tmp_path / "results.jsonl"
    path.write_text(json.dumps(record("maps", MAPS)) + "\n{not json\n")
    with pytest.raises(SystemExit, match=r"results.jsonl:2: not a JSON line"):
        table.read_records(path)


STAND_IN = """import json, sys
print("some progress")
print(json.dumps({FIGURES}))
sys.exit({CODE})
"""


def test_run_all_records_checks_targets_and_refuses_bad_lines(tmp_path):
    bench = tmp_path / "bench"
    bench.mkdir()
    slow_maps = dict(MAPS, batched_cpu_us_per_pose=3.0)  # misses the 2.5 us target
    (bench / "bench_maps.py").write_text(
        STAND_IN.replace("{FIGURES}", repr(slow_maps)).replace("{CODE}", "0"))
    (bench / "bench_noline.py").write_text("print('done, no JSON')\n")
    (bench / "bench_crash.py").write_text(
        STAND_IN.replace("{FIGURES}", "{}").replace("{CODE}", "3"))
    results = tmp_path / "out" / "results.jsonl"

    def run(*names):
        return subprocess.run([sys.executable, str(BENCH / "run_all.py"), "--bench-dir",
                               str(bench), "--results", str(results), *names],
                              capture_output=True, text=True, timeout=120)

    done = run("maps")
    assert done.returncode == 1, done.stdout + done.stderr  # a target missed
    assert "target batched kernel, us CPU/pose <= 2.5: 3 -> NOT MET" in done.stdout
    (rec,) = [json.loads(line) for line in results.read_text().splitlines()]
    assert rec["figures"] == slow_maps and rec["benchmark"] == "maps"
    assert rec["mode"] == "full" and rec["args"] == []
    head = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True)
    assert rec["git_commit"] == (head.stdout.strip() if head.returncode == 0 else None)
    assert len(rec["machine"]["load_average_before"]) == 3 and rec["machine"]["cpu_count"] >= 1
    assert rec["targets"]["batched kernel, us CPU/pose <= 2.5"] == "NOT MET"

    for name in ("noline", "crash"):
        failed = run(name)
        assert failed.returncode == 2 and f"{name}: FAILED" in failed.stdout
    assert len(results.read_text().splitlines()) == 1  # failures are not recorded

    custom = run("maps", "--args", "maps=--sample 10")
    assert custom.returncode == 1
    last = json.loads(results.read_text().splitlines()[-1])
    assert last["mode"] == "custom" and last["args"] == ["--sample", "10"]
    assert run("nosuch").returncode != 0
