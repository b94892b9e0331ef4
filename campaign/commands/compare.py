"""``campaign compare A B``: did the joint stiffness change between two campaigns?"""

from __future__ import annotations

import json
from pathlib import Path

import typer


def register(app: typer.Typer) -> None:
    @app.command("compare")
    def compare_cmd(
        a: Path = typer.Argument(..., help="Campaign A: run directory, analysis directory "
                                 "or results.json."),
        b: Path = typer.Argument(..., help="Campaign B (same robot, measured separately)."),
        alpha: float = typer.Option(0.05, help="False-alarm rate over all joints compared."),
        plot: Path = typer.Option(None, help="Write the comparison plot (.png, .pdf or .svg) "
                                  "here."),
        report: Path = typer.Option(None, help="Write report.html and report.pdf of the "
                                    "comparison into this directory."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units)."),
    ) -> None:
        """Per joint: k_B - k_A with its interval, z score and verdict."""
        from analysis.identification.compare import compare, level_text, load_campaign
        from analysis.identification.compare_plot import check_plot_path, plot_comparison

        if plot is not None:
            check_plot_path(plot)
        result = compare(load_campaign(a), load_campaign(b), alpha)
        if plot is not None:
            plot_comparison(result, plot)
            result["plot"] = str(plot)
        if report is not None:  # the report: both runs named, verdict first
            from analysis.report.compare_report import build_compare_report, run_facts
            from analysis.report.write import write_report

            files = write_report(build_compare_report(
                result, run_facts("A", result["A"]), run_facts("B", result["B"])), report)
            result["report"] = {k: str(v) for k, v in files.items()}
        if as_json:
            for note in result["notes"]:
                typer.echo(f"note: {note}", err=True)
            typer.echo(json.dumps(result, indent=2))
            return
        typer.echo(f"{result['robot']}: B = {result['B']}")
        typer.echo(f"  vs A = {result['A']}")
        typer.echo("k in kN m/rad; interval of k_B - k_A at the verdict's level,")
        typer.echo(f"  {level_text(result)}")
        typer.echo(f"{'joint':>5} {'k_A':>8} {'k_B':>8} {'diff %':>7} {'interval':>17} "
                   f"{'z':>6}  verdict")
        for r in result["joints"]:
            lo, hi = (v / 1e3 for v in r["interval_difference_Nm_per_rad"])
            typer.echo(f"{'k' + str(r['joint']):>5} {r['k_A_Nm_per_rad'] / 1e3:8.2f} "
                       f"{r['k_B_Nm_per_rad'] / 1e3:8.2f} {100 * r['relative_difference']:7.2f}"
                       f" {f'[{lo:.2f}, {hi:.2f}]':>17} {r['z']:6.2f}  {r['verdict']}"
                       + (" (borderline)" if "note" in r else ""))
        typer.echo(f"verdict: changed when |z| > {result['critical_z']:.3f} (two-sided); "
                   "z > 0: B stiffer")
        for note in result["notes"]:
            typer.echo(f"note: {note}")
        if plot is not None:
            typer.echo(f"wrote {plot}")
        for path in (result.get("report") or {}).values():
            typer.echo(f"wrote {path}")
