"""``campaign compare A B``: did the joint stiffness change between two campaigns?"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from campaign.cli_common import echo


def register(app: typer.Typer) -> None:
    @app.command("compare")
    def compare_cmd(
        a: Path = typer.Argument(..., help="Campaign A: run directory, analysis directory "
                                 "or results.json."),
        b: Path = typer.Argument(..., help="Campaign B (same robot)."),
        alpha: float = typer.Option(0.05, help="False-alarm rate over all joints compared."),
        plot: Path = typer.Option(None, help="Write the comparison plot (PNG) here."),
        as_json: bool = typer.Option(False, "--json", help="Print JSON (SI units)."),
    ) -> None:
        """Per joint: k_B - k_A with its 95 % interval, z score and verdict."""
        from analysis.identification.compare import compare, load_campaign, plot_comparison

        result = compare(load_campaign(a), load_campaign(b), alpha)
        if plot is not None:
            plot_comparison(result, plot)
            result["plot"] = str(plot)
        if as_json:
            typer.echo(json.dumps(result, indent=2))
            return
        for line in compare_lines(result):
            echo(line)


def compare_lines(result: dict) -> list[str]:
    """The comparison as text lines of at most 80 columns (stiffness in kN m/rad)."""
    from analysis.report.formatting import k_kNm, percent, sig

    lines = [f"{result['robot']}: B = {result['B']} vs A = {result['A']}",
             "k in kN m/rad; diff = (k_B - k_A) / k_A; 95 % interval of k_B - k_A; z on the "
             "compliances 1/k (z > 0: B softer)",
             f"{'':3} {'k_A':>8} {'k_B':>8} {'diff %':>7} {'95 % interval':>17} {'z':>6}  "
             "verdict"]
    for r in result["joints"]:
        lo, hi = (sig(v / 1e3, 4) for v in r["ci95_difference_Nm_per_rad"])
        lines.append(f"{'k' + str(r['joint']):3} {k_kNm(r['k_A_Nm_per_rad']):>8} "
                     f"{k_kNm(r['k_B_Nm_per_rad']):>8} {percent(r['relative_difference']):>7} "
                     f"{f'[{lo}, {hi}]':>17} {sig(r['z'], 3):>6}  {r['verdict']}")
    lines.append(f"verdict: |z| > {result['critical_z']:.3f} (two-sided, alpha "
                 f"{result['alpha']:g} shared over {len(result['joints'])} joints)")
    if result.get("plot"):
        lines.append(f"wrote {result['plot']}")
    return lines
