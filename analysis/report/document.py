"""The report as data: sections of paragraphs, tables and figures, ready to render.

Numbers are formatted once (:mod:`analysis.report.formatting`) into the
strings stored here, so the HTML and the PDF show identical text.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Paragraph:
    """A paragraph; ``kind`` is ``text``, ``heading``, ``facts`` (the key facts line),
    ``note``, ``warning`` (highlighted), ``verdict`` (the one-line verdict of a result the
    checks support) or ``refusal`` (a result kept despite a refusal: red)."""

    text: str
    kind: str = "text"


@dataclass
class Table:
    """A table of strings. ``columns`` carry their units, e.g. ``"k (kN m/rad)"``.

    ``marked[i]`` highlights row i (outlier, failed test); ``caption`` explains marks.
    ``marked`` is for failures only (a failed test, an outlier, a check not passed).
    ``widths`` are relative column widths for the PDF (default: from the text lengths).
    """

    title: str
    columns: list[str]
    rows: list[list[str]]
    marked: list[bool] = field(default_factory=list)
    caption: str = ""
    widths: list[float] | None = None
    mono: bool = False
    tall: bool = False  # rows high enough to sign in (the approval block)

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
    """A PNG image (bytes) with its caption; ``width`` x ``height`` is the display size in
    CSS pixels (the PNG itself holds :data:`analysis.report.figures.DPI` /
    :data:`analysis.report.figures.DISPLAY_DPI` times more pixels each way, 300 px per
    inch)."""

    name: str
    png: bytes
    width: int
    height: int
    caption: str
    texts: list[str] = field(default_factory=list)  # every text drawn in the figure
    label_boxes: list[tuple[float, float, float, float]] = field(default_factory=list)
    # pixel boxes (x0, y0, x1, y1) of the pose labels, for the overlap check


Block = Paragraph | Table | Figure


@dataclass
class Section:
    """A titled part of the report (the PDF flows: a section starts a page only when its
    heading and first lines would not fit)."""

    title: str
    blocks: list[Block] = field(default_factory=list)


@dataclass
class Trace:
    """What every page footer carries: report ID, generation time (UTC), software.

    ``report_id``: stable hash of the inputs and results (also ``report_id`` of
    results.json, :mod:`analysis.report.traceability`); '' when not stamped.
    """

    report_id: str = ""
    generated_utc: str = ""
    software: str = ""


@dataclass
class Report:
    """Title, a one-line status (partial run, flags) and the sections.

    ``simulated``: the data came from the simulated lab; every page and screen then
    carries a SIMULATED DATA banner (``simulated_text``, e.g. naming which of two compared
    runs is simulated). ``trace``: the footer's facts.
    """

    title: str
    subtitle: str
    sections: list[Section]
    banner: list[str] = field(default_factory=list)
    simulated: bool = False
    trace: Trace = field(default_factory=Trace)
    #: the banner's text when ``simulated`` (default: ``html.SIMULATED_TEXT``, "this run")
    simulated_text: str = ""
