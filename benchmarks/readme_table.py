"""The benchmark table of docs/benchmarks.md, generated from benchmarks/results/results.jsonl.

(The file keeps its name from when the table lived in the README.)

For each benchmark the row shows its latest *full* run (the benchmark's own
default sizes); a benchmark with no full run shows its latest quick or custom
run, marked as such. Every number in the table comes from the recorded JSON
(the benchmark's figures, the machine's load average, the date and commit);
only the prose of the "what" column is static, here.

The table sits in docs/benchmarks.md (:data:`PAGE`) between :data:`START` and :data:`END`.

Run: ``python benchmarks/readme_table.py`` rewrites the table;
``--check`` exits 1 if docs/benchmarks.md differs from what the results give.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from targets import MET, MISSED, NOT_MEASURED, check_all  # noqa: E402

RESULTS = HERE / "results" / "results.jsonl"
#: the page that holds the table
PAGE = HERE.parent / "docs" / "benchmarks.md"
START = "<!-- bench-table:start -->"
END = "<!-- bench-table:end -->"

#: row order of the table; benchmarks not listed here follow, in name order
ORDER = ("maps", "identification", "large_import", "csv_io", "planner", "compensate",
         "place", "fake_campaign", "startup")


def read_records(path: Path) -> list[dict]:
    """The records of a results.jsonl, in file order (oldest first)."""
    records = []
    for no, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError as exc:
            raise SystemExit(f"{path}:{no}: not a JSON line ({exc})") from None
        if not (isinstance(rec, dict) and isinstance(rec.get("figures"), dict)
                and isinstance(rec.get("benchmark"), str)):
            raise SystemExit(f"{path}:{no}: a record needs 'benchmark' and a 'figures' object")
        records.append(rec)
    return records


def latest(records: list[dict]) -> dict[str, dict]:
    """{benchmark: record}: the last full run of each, else its last run of any mode."""
    out: dict[str, dict] = {}
    for rec in records:
        name = rec["benchmark"]
        if name not in out or rec.get("mode") == "full" or out[name].get("mode") != "full":
            out[name] = rec
    order = {n: i for i, n in enumerate(ORDER)}
    return dict(sorted(out.items(), key=lambda kv: (order.get(kv[0], len(order)), kv[0])))


def num(x) -> str:
    """A figure as printed in the table; ``?`` when the JSON does not have it."""
    if x is None:
        return "?"
    if isinstance(x, bool):
        return "yes" if x else "no"
    if isinstance(x, int):
        return f"{x:,}".replace(",", " ")
    if isinstance(x, float):
        if x != 0 and abs(x) < 1e-3:
            return f"{x:.1e}"
        if abs(x) >= 1e3:
            return f"{x:,.0f}".replace(",", " ")
        return f"{x:.3g}"
    if isinstance(x, list):
        return ", ".join(num(v) for v in x)
    return str(x)


class Fig:
    """Figures of one record; ``f["a.b"]`` formats a (nested) figure, ``?`` if missing."""

    def __init__(self, figures: dict) -> None:
        self.figures = figures

    def get(self, path: str):
        node = self.figures
        for part in path.split("."):
            if not isinstance(node, dict) or part not in node:
                return None
            node = node[part]
        return node

    def __getitem__(self, path: str) -> str:
        return num(self.get(path))


def _rel(f: Fig, path: str) -> str:
    """A relative difference (dict of them or one value)."""
    v = f.get(path)
    if isinstance(v, dict):
        return ", ".join(f"{k} {num(x)}" for k, x in v.items())
    return num(v)


# Each row: (what, figure, baseline, ratio), functions of the figures. The baseline
# column says what the baseline is and how both sides are timed (the benchmark's
# own "timing" text).

def _maps(f: Fig) -> tuple[str, str, str, str]:
    s = f.get("batched_cpu_us_per_pose")
    n = f.get("poses")
    total = f" ({num(s * n / 1e6)} s)" if s is not None and n is not None else ""
    return (f"{f['grid_step_deg']} deg (theta2, theta3) map of the {f['robot']}: {f['poses']} "
            "poses of 1/kappa_F, v_p, v_r (J, K_C, two deflections each)",
            f"{f['batched_cpu_us_per_pose']} us CPU/pose, single-threaded{total}; threaded: "
            f"{f['threaded_wall_us_per_pose']} us wall/pose on {f['cpus']} CPUs",
            f"{f['baseline']}: {f['loop_cpu_us_per_pose']} us CPU/pose on {f['loop_sample']} "
            f"sampled poses; outputs agree to {_rel(f, 'max_rel_diff')} (max relative "
            f"difference). Timed: {f['timing']}",
            f"{f['ratio_cpu']}x CPU ({f['ratio_wall']}x wall)")


def _identification(f: Fig) -> tuple[str, str, str, str]:
    return (f"{f['trials']} identifications of {f['tests']} tests (batched OLS, MGS QR with "
            f"the trials on the last axis); the robustness study at {f['study_trials']} "
            f"trials of {f['tests']} tests (draws, measured Jacobians, fits)",
            f"OLS {f['batched_ols_cpu_s']} s CPU, WLS {f['batched_wls_cpu_s']} s CPU; study "
            f"{f['study_cpu_s']} s CPU ({f['study_wall_s']} s wall)",
            f"{f['baseline']}: {f['loop_cpu_s_scaled']} s CPU (per-trial cost of "
            f"{f['loop_sample']} trials scaled to {f['trials']}); estimates agree to "
            f"{_rel(f, 'max_rel_diff')} relative. Timed: {f['timing']}",
            f"{f['ratio_cpu']}x CPU")


def _large_import(f: Fig) -> tuple[str, str, str, str]:
    sizes = sorted((f.get("large") or {}), key=int)
    runs, checks = [], []
    for n in sizes:
        row = f.get("large")[n]  # {method: figures}, in the benchmark's order
        parts, checked = [], []
        for method, figures in row.items():
            r = Fig(figures)
            parts.append(f"{method} {r['cpu_s']} s CPU / {r['peak_rss_MB']} MB")
            if r.get("x_rel_diff_vs_lstsq") is not None:
                checked.append(f"OLS compliances vs `np.linalg.lstsq` on the dense design, "
                               f"with the wrench errors-in-variables correction written out, "
                               f"{r['x_rel_diff_vs_lstsq']}")
            if r.get("se_rel_diff_vs_dense_sandwich") is not None:
                checked.append(f"OLS standard errors vs the dense G Sigma G^T "
                               f"{r['se_rel_diff_vs_dense_sandwich']}")
            if r.get("max_abs_k_error_in_se") is not None:
                checked.append(f"{method} k within {r['max_abs_k_error_in_se']} standard "
                               "errors of the truth")
        poses = Fig(next(iter(row.values()), {}))["n_poses"]
        runs.append(f"N={num(int(n))} ({poses} poses): " + ", ".join(parts))
        if checked:
            checks.append(f"N={num(int(n))}: " + ", ".join(checked))
    small = {}  # {tests: [method s]} from keys analyze_<tests>_tests_validation_<method>
    for key, r in (f.get("small") or {}).items():
        m = re.fullmatch(r"analyze_(\d+)_tests_validation_(\w+)", key)
        if m and isinstance(r, dict):
            small.setdefault(int(m[1]), []).append(f"{m[2]} {num(r.get('cpu_s'))} s")
    figure = "; ".join(runs + [f"{num(n)} tests with validation: {', '.join(v)} CPU"
                               for n, v in small.items()])
    figure += f"; demo analysis with its report: {f['small.demo_analyze_with_report.cpu_s']} s CPU"
    baseline = (f"demo analysis: `{f['baseline']}` "
                f"{f['small.import_numpy_pandas_pyplot_pinocchio.cpu_s']} s CPU; large imports: "
                "no other implementation, outputs checked: "
                + ("; ".join(checks) or "none recorded") + f". Timed: {f['timing']}")
    return ("`campaign analyze --measurements FILE --robot kr240-2 --no-report "
            "--accept-misfit` with leave-one-pose-out validation on N simulated KR240-2 "
            "tests, ols and exact; a small file with validation; the demo run's analysis "
            "with its report", figure, baseline,
            f"demo {f['small.demo_analyze_over_imports']}x the imports (CPU)")


def _planner(f: Fig) -> tuple[str, str, str, str]:
    at = f.get("batched_cpu_us_per_candidate_at") or {}
    sizes = "; ".join(f"{num(v)} at {num(int(n))}" for n, v in
                      sorted(at.items(), key=lambda kv: int(kv[0])))
    return (f"candidates (x {f['load_cases']} load cases) to a {f['design_tests']}-test "
            "D-optimal design (KR240-2 protocol)",
            f"{f['batched_cpu_us_per_candidate']} us CPU/candidate at "
            f"{f['baseline_candidates']} candidates; {sizes}",
            f"{f['baseline']}: {f['loop_cpu_us_per_candidate']} us CPU/candidate at "
            f"{f['baseline_candidates']}; same design: {f['same_design']}. Timed: {f['timing']}",
            f"{f['ratio_cpu']}x CPU ({f['ratio_wall']}x wall)")


def _compensate(f: Fig) -> tuple[str, str, str, str]:
    return (f"`compensate` on a {f['points']}-point KR240-2 path: checks, deflection with "
            "covariance, Newton compensation on the equilibrium",
            f"{f['batched_s']} s wall, {f['batched_cpu_s']} s CPU "
            f"({f['batched_points_per_s']} points/s wall)",
            f"{f['baseline']}: {f['loop_points_per_s']} points/s wall, "
            f"{f['loop_cpu_points_per_s']} CPU, on {f['sample']} points; "
            + (f"outputs agree: {_rel(f, 'max_rel_diff')} (q_cmd: max absolute difference, "
               "rad; the others: max difference relative to the largest value)"
               if f.get("max_rel_diff") is not None else
               f"max |q_cmd difference| {f['max_q_cmd_difference_rad']} rad, max deflection "
               f"difference {f['max_deflection_difference']}") + f". Timed: {f['timing']}",
            f"{f['ratio']}x wall, {f['ratio_cpu']}x CPU")


def _place(f: Fig) -> tuple[str, str, str, str]:
    return ("placement search inner work: closed-form IK + limits + J + deflection under a "
            f"tool-frame wrench, KR240-2, {f['evaluations']} (placement, point, angle) "
            "evaluations",
            f"{f['batched_evaluations_per_s']}/s wall, {f['batched_cpu_evaluations_per_s']}/s "
            f"CPU; whole search step {f['search_step_evaluations_per_s']}/s wall; tool offset "
            f"sideways {f['offset_tool_batched_evaluations_per_s']}/s wall"
            + "".join(f"; `campaign place` {name} ({f[p + 'evaluations']} evaluations, "
                      f"{f.get(p + 'where')}): wall {f[p + 'wall_s']} s, user "
                      f"{f[p + 'user_s']} s, system {f[p + 'system_s']} s; search "
                      f"{f[p + 'search_s']} s at {f[p + 'evaluations_per_s']}/s, estimated "
                      f"{f[p + 'expected_s']} s"
                      + (f" (x{f[p + 'estimate_ratio']}; {f[p + 'core_share']} of a core per "
                         f"process at load {f[p + 'load_average_at_start']}; the probe's wall "
                         f"time alone: {f[p + 'expected_probe_wall_s']} s, "
                         f"x{f[p + 'estimate_ratio_probe_wall']})"
                         if f.get(p + "core_share") is not None else "")
                      + f"; probe {f[p + 'probe_per_process_per_s']}/s per process"
                      + (f"; workers' evaluations per CPU s {f[p + 'cpu_rate_over_probe']} of "
                         "the probe's" if f.get(p + "cpu_rate_over_probe") is not None else "")
                      + f"; tasks of {f[p + 'placements_per_task']}"
                      for name in (f.get("commands") or {})
                      for p in (f"commands.{name}.",)),
            f"{f['baseline']}: {f['loop_evaluations_per_s']}/s wall, "
            f"{f['loop_cpu_evaluations_per_s']}/s CPU on {f['sample']} points; the general "
            f"batched route {f['general_batched_evaluations_per_s']}/s wall; outputs agree: "
            f"{f['outputs_agree']}"
            + (f" (loop: max difference {f['loop_max_rel_diff']} of the largest deflection)"
               if f.get("loop_max_rel_diff") is not None else "")
            + f". Timed: {f['timing']}",
            f"{f['ratio']}x wall, {f['ratio_cpu']}x CPU; {f['ratio_vs_general_batched']}x the "
            "general batched route (wall)")


def _fake_campaign(f: Fig) -> tuple[str, str, str, str]:
    return ("the built-in KR240-2 protocol's plan with `acquire --fake`, real drivers over "
            f"loopback, at time scales {f['scales']}, {f['repeat']} repeats each",
            f"least-squares fit of wall = overhead + lab_time/s to all runs: overhead "
            f"{f['overhead_s']} +- {f['overhead_se_s']} s, lab time {f['lab_time_s']} +- "
            f"{f['lab_time_se_s']} s of robot time; per-repeat fits: overhead "
            f"{f['overhead_per_repeat_s']} s, lab time {f['lab_time_per_repeat_s']} s; largest "
            f"residual {f['max_abs_residual_s']} s",
            f"{f['baseline']}. Timed: {f['timing']}", "-")


def _startup(f: Fig) -> tuple[str, str, str, str]:
    rows = f.get("command_help")
    if rows is None:  # a record from before the per-command figures (issue 22)
        return (f"start-up CPU of `{f['help_command']}` and `{f['stiffness_command']}` (one "
                "pose); outputs checked (every command listed; K_X and deflection equal the "
                "library's)",
                f"{f['help_cpu_s']} s / {f['stiffness_cpu_s']} s CPU",
                f"`{f['help_reference']}` {f['help_ref_cpu_s']} s / "
                f"`{f['stiffness_reference']}` {f['stiffness_ref_cpu_s']} s CPU. "
                f"Timed: {f['timing']}",
                f"{f['help_ratio']}x / {f['stiffness_ratio']}x CPU")
    cpus = [r["cpu_s"] for r in rows.values()]
    heavy = f.get("command_help_heavy_imports") or []
    return (f"start-up CPU of `{f['help_command']}`, of each of the {len(rows)} "
            f"`campaign <cmd> --help` and of `{f['stiffness_command']}` (one pose); outputs "
            "checked (every command listed, the same Commands panel as the baseline app; "
            "K_X and deflection equal the library's)",
            f"`--help` {f['help_cpu_s']} s; `<cmd> --help` {num(min(cpus))}-{num(max(cpus))} s "
            f"(heavy libraries imported: {', '.join(heavy) or 'none'}); stiffness "
            f"{f['stiffness_cpu_s']} s CPU",
            f"{f['help_reference']}: {f['help_ref_cpu_s']} s, and its `<cmd> --help` (the "
            "help line only, no options); for stiffness "
            f"`{f['stiffness_reference']}` {f['stiffness_ref_cpu_s']} s CPU. Timed: "
            f"{f['timing']}",
            f"`--help` {f['help_ratio']}x; worst `<cmd> --help` {f['command_help_worst_ratio']}x "
            f"({f['command_help_worst']}); stiffness {f['stiffness_ratio']}x CPU")


def _csv_io(f: Fig) -> tuple[str, str, str, str]:
    sizes = sorted((f.get("read") or {}), key=int)
    read = [f"N={num(int(n))}: {f[f'read.{n}.arrow.cpu_s']} s CPU / "
            f"{f[f'read.{n}.arrow.peak_rss_MB']} MB peak (imports alone "
            f"{f[f'read.{n}.imports.cpu_s']} s / {f[f'read.{n}.imports.peak_rss_MB']} MB)"
            for n in sizes]
    base = [f"N={num(int(n))}: {f[f'read.{n}.table.cpu_s']} s / "
            f"{f[f'read.{n}.table.peak_rss_MB']} MB, same arrays {f[f'read.{n}.same_arrays']}"
            for n in sizes]
    ratio = [f"N={num(int(n))}: {f[f'read.{n}.ratio_peak_above_imports']}x less memory above "
             f"the imports, {f[f'read.{n}.ratio_cpu_read']}x CPU" for n in sizes]
    return ("tests CSV read into the arrays (`read_test_arrays`); residuals.csv of "
            f"{f['write.tests']} tests ({f['write.rows']} rows, {f['write.file_MB']} MB) "
            "written by `table_csv`",
            "; ".join(read) + f"; write {f['write.table_csv_cpu_s']} s CPU",
            "read: `to_arrays(read_csv(...))` " + "; ".join(base) + "; write: pandas "
            f"`to_csv` {f['write.pandas_cpu_s']} s CPU, same bytes {f['write.same_bytes']}. "
            f"Timed: {f['timing']}",
            "; ".join(ratio) + f"; write {f['write.ratio_cpu']}x CPU")


def _generic(f: Fig) -> tuple[str, str, str, str]:
    return ("(no description in readme_table.py)", json.dumps(f.figures), "?", "?")


def _gui_sensitivity(f: Fig) -> tuple[str, str, str, str]:
    return (f"sensitivity explorer of `campaign gui`: {f['moves']} slider moves, "
            f"{num(f['trials'])} trials ({f['method']}), API round trip over loopback",
            f"median {f['round_trip_ms_median']} ms, p90 {f['round_trip_ms_p90']} ms wall"
            + (f"; the server's CPU per move median {f['server_cpu_ms_median']} ms, p90 "
               f"{f['server_cpu_ms_p90']} ms (user + system, 10 ms ticks)"
               if "server_cpu_ms_p90" in f.figures else ""),
            f"the job in-process {f['job_ms_median']} ms"
            + (f" ({f['job_cpu_ms_median']} ms CPU)" if "job_cpu_ms_median" in f.figures
               else "") + " (numbers equal: max relative "
            f"difference {f['max_rel_diff']}). Timed: {f['timing']}",
            f"HTTP + JSON {f['overhead_ms_median']} ms")


def _acquire_state(f: Fig) -> tuple[str, str, str, str]:
    return (f"`GET /api/acquire/state` while a run writes: its events file of "
            f"{num(f['events'])} lines ({f['file_bytes'] / 1e6:.2f} MB), one line appended "
            "per poll",
            f"incremental reading {f['incremental_cpu_ms_per_poll']} ms CPU/poll "
            f"({f['incremental_ms_per_poll']} ms wall)",
            f"the whole file read per poll: {f['full_cpu_ms_per_poll']} ms CPU/poll "
            f"({f['full_ms_per_poll']} ms wall); answers equal {f['answers_equal']}",
            f"{f['ratio_wall']}x wall")


def _ledger(f: Fig) -> tuple[str, str, str, str]:
    return (f"`campaign history list` and `trend` of one robot in an SQLite ledger of "
            f"{num(f['robots'])} robots x {f['campaigns_per_robot']} campaigns "
            f"({f['file_MB']} MB)",
            f"list {f['list_s_max']} s, trend {f['trend_s_max']} s wall (worst of "
            f"{f['repeat']} robots; answers checked {f['answers_checked']})",
            f"none (absolute target). Timed: {f['timing']}", "-")


def _links(f: Fig) -> tuple[str, str, str, str]:
    return ("`maps` (1 deg KR240-2 map) and `compensate` (a "
            f"{f['path_points']}-point path) with a model file's link compliance",
            f"maps {f['maps_links_cpu_us_per_pose']} us CPU/pose, compensate "
            f"{f['compensate_links_cpu_us_per_pose']} us CPU/point",
            f"{f['baseline']}: maps {f['maps_joints_cpu_us_per_pose']} us CPU/pose, compensate "
            f"{f['compensate_joints_cpu_us_per_pose']} us CPU/point. Timed: {f['timing']}",
            f"links / joints: maps {f['maps_ratio_cpu']}x CPU, compensate "
            f"{f['compensate_ratio_cpu']}x CPU"
            + (f"; compensator law / joints: maps {f['maps_law_ratio_cpu']}x CPU, "
               f"compensate {f['compensate_law_ratio_cpu']}x CPU"
               if "compensate_law_ratio_cpu" in f.figures else ""))


def _model_classes(f: Fig) -> tuple[str, str, str, str]:
    return (f"`--model auto` on the shop lab: one all-effects campaign of the model-class "
            f"study (seed {f['seed']}), and its two batched stages: the realistic-arm physics "
            "model with its 8 forward differences, joint 2's flank patterns on the 61 x 61 "
            "spring grid (outputs checked identical to the loops)",
            f"campaign {f['campaign_cpu_s']} s CPU; physics model "
            f"{f['physics_batched_cpu_ms']} ms, flank grid {f['flank_batched_cpu_ms']} ms CPU",
            f"{f['baseline']}: physics model {f['physics_loop_cpu_ms']} ms, flank grid "
            f"{f['flank_loop_cpu_ms']} ms CPU. Timed: {f['timing']}",
            f"loop / batched: physics model {f['physics_speedup_cpu']}x, flank grid "
            f"{f['flank_speedup_cpu']}x CPU")


ROWS: dict[str, Callable[[Fig], tuple[str, str, str, str]]] = {
    "maps": _maps, "identification": _identification, "large_import": _large_import,
    "planner": _planner, "compensate": _compensate, "place": _place,
    "fake_campaign": _fake_campaign, "startup": _startup, "csv_io": _csv_io,
    "gui_sensitivity": _gui_sensitivity, "acquire_state": _acquire_state, "ledger": _ledger,
    "links": _links, "model_classes": _model_classes,
}


def targets_cell(name: str, figures: dict) -> str:
    """Every target of the benchmark with its figure and status."""
    cells = []
    for t, status, value in check_all(name, figures):
        shown = num(value) if value is not None else "-"
        mark = {MET: "met", MISSED: "**NOT MET**",
                NOT_MEASURED: f"not measured (needs {t.requires})"}[status]
        cells.append(f"{t.text()} ({t.source}): {shown}, {mark}")
    return "; ".join(cells) or "none"


def measured_cell(rec: dict) -> str:
    """Load average (1 min) before -> after, date, commit and run mode."""
    m = rec.get("machine", {})
    before, after = m.get("load_average_before"), m.get("load_average_after")
    load = (f"load {num(before[0])} -> {num(after[0])}" if before and after else "load ?")
    commit = (rec.get("git_commit") or "?")[:8] + (" (modified)" if rec.get("git_dirty") else "")
    mode = rec.get("mode", "?")
    mode = "full run" if mode == "full" else f"**{mode} run** ({' '.join(rec.get('args', []))})"
    return f"{load}; {rec.get('date_utc', '?')}; {commit}; {mode}"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def render(records: list[dict], source: str = "benchmarks/results/results.jsonl") -> str:
    """The generated block: one sentence on the machines, then the table."""
    rows = latest(records)
    machines = sorted({(r.get("machine", {}).get("cpu_model") or "?",
                        r.get("machine", {}).get("cpu_count"), r.get("python", "?"),
                        r.get("numpy", "?")) for r in rows.values()}, key=str)
    where = "; ".join(f"{model}, {num(cpus)} CPUs, Python {py}, numpy {np_}"
                      for model, cpus, py, np_ in machines)
    lines = [
        f"Generated by `benchmarks/readme_table.py` from `{source}` (the latest full run of "
        "each benchmark, else its latest quick run, marked); do not edit by hand. "
        f"Measured on: {where}. The load average is the machine's 1-minute figure before "
        "and after the benchmark ran.",
        "",
        "| script | what | figure | baseline (what, and how both sides are timed) | ratio | "
        "targets | measured |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, rec in rows.items():
        f = Fig(rec["figures"])
        what, figure, baseline, ratio = ROWS.get(name, _generic)(f)
        script = rec.get("script", f"benchmarks/bench_{name}.py")
        cells = [f"`{script}`", what, figure, baseline, ratio,
                 targets_cell(name, rec["figures"]), measured_cell(rec)]
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return "\n".join(lines)


def replace_block(text: str, block: str, path: Path = PAGE) -> str:
    """``text`` with the part between START and END replaced by ``block``."""
    i, j = text.find(START), text.find(END)
    if i < 0 or j < i:
        raise SystemExit(f"{path}: no '{START}' ... '{END}' markers")
    return text[:i + len(START)] + "\n" + block + "\n" + text[j:]


def update_page(page: Path = PAGE, results: Path = RESULTS) -> bool:
    """Rewrite the table of ``page`` (docs/benchmarks.md) from ``results``; True if the
    file changed."""
    text = page.read_text()
    new = replace_block(text, render(read_records(results)), page)
    if new != text:
        page.write_text(new)
    return new != text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--results", type=Path, default=RESULTS)
    parser.add_argument("--page", type=Path, default=PAGE)
    parser.add_argument("--check", action="store_true",
                        help="exit 1 if the page's table differs from the results")
    args = parser.parse_args()
    if args.check:
        text = args.page.read_text()
        if replace_block(text, render(read_records(args.results)), args.page) != text:
            print(f"{args.page}: the benchmark table differs from {args.results}; run "
                  "python benchmarks/readme_table.py")
            return 1
        print(f"{args.page}: the benchmark table matches {args.results}")
        return 0
    changed = update_page(args.page, args.results)
    print(f"{args.page}: table {'regenerated' if changed else 'unchanged'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
