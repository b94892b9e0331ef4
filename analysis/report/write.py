"""Write the report files (``report.html``, ``report.pdf``) into an output directory."""

from __future__ import annotations

from pathlib import Path

from analysis.errors import InputError
from analysis.output_files import make_dir, write_bytes, write_text
from analysis.report.document import Report
from analysis.report.html import render_html
from analysis.report.pdf import render_pdf


def write_report(report: Report, out_dir: str | Path) -> dict[str, Path]:
    """Render ``report`` to HTML and PDF in ``out_dir``; returns the paths by name."""
    out = make_dir(out_dir)
    try:
        paths = {"html": out / "report.html", "pdf": out / "report.pdf"}
        write_text(paths["html"], render_html(report))
        write_bytes(paths["pdf"], render_pdf(report))
    except OSError as err:
        raise InputError(f"cannot write the report: {err.strerror}", where=str(out)) from err
    return paths
