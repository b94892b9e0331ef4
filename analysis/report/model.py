"""The report as data: sections of paragraphs, tables and figures, ready to render.

Numbers are formatted once (:mod:`analysis.report.formatting`) into the
strings stored here, so the HTML and the PDF show identical text.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Paragraph:
    """A paragraph; ``kind`` is ``text``, ``note`` or ``warning`` (rendered highlighted)."""

    text: str
    kind: str = "text"


@dataclass
class Table:
    """A table of strings. ``columns`` carry their units, e.g. ``"k (kN m/rad)"``.

    ``marked[i]`` highlights row i (outlier, failed test); ``caption`` explains marks.
    ``widths`` are relative column widths for the PDF (default: from the text lengths).
    """

    title: str
    columns: list[str]
    rows: list[list[str]]
    marked: list[bool] = field(default_factory=list)
    caption: str = ""
    widths: list[float] | None = None
    mono: bool = False

    def alignment(self) -> list[str]:
        """``"left"`` for a column holding text, ``"right"`` for numbers (and intervals)."""
        out = []
        for i in range(len(self.columns)):
            cells = [r[i] for r in self.rows if r[i] not in ("-", "")]
            out.append("right" if cells and all(_numeric(c) for c in cells) else "left")
        return out

    def __post_init__(self) -> None:
        if not self.marked:
            self.marked = [False] * len(self.rows)
        for row in self.rows:
            if len(row) != len(self.columns):
                raise ValueError(f"table {self.title!r}: row of {len(row)} cells for "
                                 f"{len(self.columns)} columns")


def _numeric(text: str) -> bool:
    """A number, a number with a trailing mark (``12.3 *``) or an interval ``[a, b]``."""
    parts = text.strip("[]").replace(" *", "").split(",")
    try:
        for p in parts:
            float(p)
    except ValueError:
        return False
    return True


@dataclass
class Figure:
    """A PNG image (bytes) of ``width`` x ``height`` pixels with its caption."""

    name: str
    png: bytes
    width: int
    height: int
    caption: str


Block = Paragraph | Table | Figure


@dataclass
class Section:
    """A titled part of the report; in the PDF each section starts on a new page."""

    title: str
    blocks: list[Block] = field(default_factory=list)


@dataclass
class Report:
    """Title, a one-line status (partial run, flags) and the sections."""

    title: str
    subtitle: str
    sections: list[Section]
    banner: list[str] = field(default_factory=list)
