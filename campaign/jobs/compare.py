"""The ``compare`` job: per joint, k_B - k_A with its interval, z score and verdict; optionally
the comparison plot and report."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class CompareOptions:
    """a, b: run directory, analysis directory or results.json of campaigns A and B;
    alpha: false-alarm rate over all joints compared; plot: the comparison plot
    (.png, .pdf or .svg) to write; report: directory of report.html/.pdf to write."""

    a: Path
    b: Path
    alpha: float = 0.05
    plot: Path | None = None
    report: Path | None = None


@dataclass
class CompareResult:
    """comparison: the document ``campaign compare --json`` prints (SI units), with the
    written ``plot`` and ``report`` files named."""

    comparison: dict

    def to_json(self) -> dict:
        return self.comparison

    @property
    def notes(self) -> list[str]:
        return list(self.comparison["notes"])


def run(o: CompareOptions) -> CompareResult:
    """Load both campaigns, compare them and write the plot and report asked for."""
    from analysis.identification.compare.comparison import compare, load_campaign
    from analysis.identification.compare.plot import check_plot_path, plot_comparison

    if o.plot is not None:
        check_plot_path(Path(o.plot))
    result = compare(load_campaign(Path(o.a)), load_campaign(Path(o.b)), o.alpha)
    if o.plot is not None:
        plot_comparison(result, Path(o.plot))
        result["plot"] = str(o.plot)
    if o.report is not None:  # the report: both runs named, verdict first
        from analysis.identification.compare.run_facts import run_facts
        from analysis.report.compare_report import build_compare_report
        from analysis.report.write import write_report

        files = write_report(build_compare_report(
            result, run_facts("A", result["A"]), run_facts("B", result["B"])), Path(o.report))
        result["report"] = {k: str(v) for k, v in files.items()}
    return CompareResult(result)
