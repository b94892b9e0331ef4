"""``campaign compare A B``: did the joint stiffness change between two campaigns?"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from analysis.errors import InputError


def register(app: typer.Typer) -> None:
    @app.command("compare")
    def compare_cmd(
        a: Path = typer.Argument(..., help="Campaign A: run directory, analysis directory "
                                 "or results.json."),
        b: Path = typer.Argument(..., help="Campaign B (same robot)."),
        alpha: float = typer.Option(0.05, help="False-alarm rate over all joints compared."),
        plot: Path = typer.Option(None, help="Write the comparison plot (PNG) here."),
        report: Path = typer.Option(None, help="Write report.html and report.pdf of the "
                                    "comparison into this directory."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units)."),
    ) -> None:
        """Per joint: k_B - k_A with its 95 % interval, z score and verdict."""
        from analysis.identification.compare import compare, load_campaign

        result = compare(load_campaign(a), load_campaign(b), alpha)
        if plot is not None or report is not None:
            # the report's figure: names A and B with their campaigns and dates
            from analysis.report.compare_report import (
                build_compare_report,
                comparison_figure,
                run_facts,
            )

            facts = run_facts("A", result["A"]), run_facts("B", result["B"])
        if plot is not None:
            try:
                plot.write_bytes(comparison_figure(result, *facts).png)
            except OSError as err:
                raise InputError(f"cannot write the plot: {err.strerror}",
                                 where=str(plot)) from err
            result["plot"] = str(plot)
        if report is not None:
            from analysis.report.write import write_report

            files = write_report(build_compare_report(result, *facts), report)
            result["report"] = {k: str(v) for k, v in files.items()}
        if as_json:
            typer.echo(json.dumps(result, indent=2))
            return
        typer.echo(f"{result['robot']}: B = {result['B']} vs A = {result['A']}")
        typer.echo(f"{'joint':>5} {'k_A (kN m/rad)':>15} {'k_B (kN m/rad)':>15} "
                   f"{'diff %':>8} {'95 % interval (kN m/rad)':>26} {'z':>7}  verdict")
        for r in result["joints"]:
            lo, hi = (v / 1e3 for v in r["ci95_difference_Nm_per_rad"])
            typer.echo(f"{'k' + str(r['joint']):>5} {r['k_A_Nm_per_rad'] / 1e3:15.2f} "
                       f"{r['k_B_Nm_per_rad'] / 1e3:15.2f} {100 * r['relative_difference']:8.2f}"
                       f" {f'[{lo:.2f}, {hi:.2f}]':>26} {r['z']:7.2f}  {r['verdict']}")
        typer.echo(f"verdict: |z| > {result['critical_z']:.3f} (two-sided, alpha "
                   f"{result['alpha']:g} shared over {len(result['joints'])} joints)")
        if plot is not None:
            typer.echo(f"wrote {plot}")
        for path in (result.get("report") or {}).values():
            typer.echo(f"wrote {path}")
