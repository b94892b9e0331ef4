"""Write the report files (``report.html``, ``report.pdf``) into an output directory."""

from __future__ import annotations

from pathlib import Path

from analysis.errors import InputError
from analysis.report.html import render_html
from analysis.report.model import Report
from analysis.report.pdf import render_pdf


def write_report(report: Report, out_dir: str | Path) -> dict[str, Path]:
    """Render ``report`` to HTML and PDF in ``out_dir``; returns the paths by name."""
    out = Path(out_dir)
    try:
        out.mkdir(parents=True, exist_ok=True)
        paths = {"html": out / "report.html", "pdf": out / "report.pdf"}
        paths["html"].write_text(render_html(report), encoding="utf-8")
        paths["pdf"].write_bytes(render_pdf(report))
    except OSError as err:
        raise InputError(f"cannot write the report: {err.strerror}", where=str(out)) from err
    return paths
