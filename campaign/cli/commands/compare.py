"""``campaign compare A B``: did the joint stiffness change between two campaigns?"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from campaign.cli.terminal import echo


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
        from campaign.jobs.compare import CompareOptions, run

        result = run(CompareOptions(a, b, alpha, plot, report)).comparison
        if as_json:
            for note in result["notes"]:
                echo(f"note: {note}", err=True)
            typer.echo(json.dumps(result, indent=2))
            return
        for line in compare_lines(result):
            echo(line)


def compare_lines(result: dict) -> list[str]:
    """The comparison as text lines of at most 80 columns (stiffness in kN m/rad, 5
    digits; the interval of k_B - k_A at the verdict's level, 4 digits)."""
    from analysis.identification.compare.comparison import level_text
    from analysis.report.formatting import k_kNm, percent, sig

    lines = [f"{result['robot']}: B = {result['B']}", f"  vs A = {result['A']}",
             "k in kN m/rad; diff = (k_B - k_A) / k_A; interval of k_B - k_A at the "
             f"verdict's level, {level_text(result)}",
             f"{'':3} {'k_A':>8} {'k_B':>8} {'diff %':>7} {'interval':>17} {'z':>6}  verdict"]
    for r in result["joints"]:
        lo, hi = (sig(v / 1e3, 4) for v in r["interval_difference_Nm_per_rad"])
        lines.append(f"{'k' + str(r['joint']):3} {k_kNm(r['k_A_Nm_per_rad']):>8} "
                     f"{k_kNm(r['k_B_Nm_per_rad']):>8} {percent(r['relative_difference']):>7} "
                     f"{f'[{lo}, {hi}]':>17} {sig(r['z'], 3):>6}  {r['verdict']}"
                     + (" (borderline)" if "note" in r else ""))
    lines.append(f"verdict: changed when |z| > {result['critical_z']:.3f} (two-sided); "
                 "z > 0: B stiffer")
    lines += [f"note: {note}" for note in result["notes"]]
    if result.get("plot"):
        lines.append(f"wrote {result['plot']}")
    lines += [f"wrote {path}" for path in (result.get("report") or {}).values()]
    return lines
