"""The analyze job's files: results.json, residuals.csv, validation.csv, model.toml, the
report (HTML and PDF) and analysis.json, written into one (new) directory."""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path

from campaign.jobs import heap
from campaign.jobs.analyze_input import AnalysisInput
from campaign.jobs.option_checks import Stage, floats, no_stage


def write_outputs(result, inp: AnalysisInput, out: Path, *, report: bool, trials: int,
                  wrench_N_Nm: Sequence[float] | None, poses_rad: Sequence[Sequence[float]],
                  run_dir: Path | None, stage: Stage = no_stage,
                  history: Callable[[Path], object] | None = None) -> dict[str, Path]:
    """Write the files of ``result`` (the identification of ``inp``) into ``out`` (a new
    directory); returns the paths of the main files by name. With ``report``: the report
    with ``trials`` Monte-Carlo trials per point, the deflection under ``wrench_N_Nm`` (N,
    N m at P, base frame; None: the report's choice) and K_X at ``poses_rad`` (rad, after
    the protocol's); ``history(out)``: the report's history section."""
    from analysis.identification.io.model_export import export_model  # model.toml, K_X
    from analysis.identification.io.results_json import write_results
    from analysis.output_files import write_text
    from analysis.report.traceability import stamp_results

    info = inp.info
    paths = write_results(result, out)
    paths.update(export_model(result, inp.robot, out, inp.tests, info))
    info.report_id = stamp_results(paths["results"], info.input_hashes())
    if report:
        # the report makes figures: matplotlib is imported only here
        from analysis.report.report_inputs import report_inputs
        from analysis.report.write import write_report

        heap.freeze_imported()
        wrench = None if wrench_N_Nm is None else floats(wrench_N_Nm, "--wrench", 6)
        inputs = report_inputs(
            robot=inp.robot, tests=inp.tests, info=info, protocol=inp.protocol,
            noise=inp.noise, wrench=wrench, true_k=inp.true_k, trials=trials,
            poses=[floats(values, f"--pose #{i}", inp.robot.n)
                   for i, values in enumerate(poses_rad, start=1)],
            history=None if history is None else (lambda: history(out)))
        with stage("report: maps, K_X, Monte-Carlo robustness, figures"):
            from analysis.report.build import build_report

            built = build_report(result, inputs)
        with stage("report: HTML and PDF"):
            paths.update(write_report(built, out))
    summary = {"run": str(run_dir) if run_dir else None, "partial": info.partial,
               "status": info.status, "failed_rows": info.n_failed}
    write_text(Path(out) / "analysis.json", json.dumps(summary, indent=2) + "\n")
    return paths
