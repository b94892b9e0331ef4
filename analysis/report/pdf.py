"""The report as a PDF made with fpdf2 (A4 portrait, flowing: a section starts a new page
only when its heading and first lines would not fit; bookmarks for sections and tables).

Fonts: the DejaVu TrueType fonts shipped with matplotlib (Unicode: deg, +-,
Greek letters), embedded in the file.
"""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
from fpdf import FPDF

from analysis.report.document import Figure, Paragraph, Report, Table

MARGIN = 15.0  # mm
FIGURE_WIDTH = 150.0  # mm
FILL = {"warning": (255, 243, 205), "note": (238, 243, 251), "verdict": (230, 244, 234),
        "refusal": (253, 226, 225)}
SIM_BAND = 9.0  # mm, height of the SIMULATED DATA band at the top of each page
KEEP_WITH_HEADING = 45.0  # mm: a heading needs this much room below it, else a new page
MARK = (253, 226, 225)
HEAD = (232, 236, 244)


def _font_dir() -> Path:
    return Path(matplotlib.get_data_path()) / "fonts" / "ttf"


class _Doc(FPDF):
    def __init__(self, title: str, simulated: bool = False, trace: str = "",
                 simulated_text: str = "") -> None:
        super().__init__(orientation="P", unit="mm", format="A4")
        self.report_title = title
        self.simulated = simulated
        self.simulated_text = simulated_text
        self.trace = trace
        self.table_header = None  # draws the current table's header after a page break
        fonts = _font_dir()
        self.add_font("DejaVu", "", str(fonts / "DejaVuSans.ttf"))
        self.add_font("DejaVu", "B", str(fonts / "DejaVuSans-Bold.ttf"))
        self.add_font("DejaVuMono", "", str(fonts / "DejaVuSansMono.ttf"))
        self.set_margins(MARGIN, MARGIN + (SIM_BAND if simulated else 0.0), MARGIN)
        self.set_auto_page_break(True, margin=MARGIN + 8)
        self.set_title(title)
        self.set_creator("stiffness-campaign")

    def header(self) -> None:
        if not self.simulated:
            return
        from analysis.report.html import SIMULATED_TEXT

        self.set_fill_color(204, 0, 0)
        self.set_text_color(255)
        self.set_font("DejaVu", "B", 9)
        self.set_xy(MARGIN, 5)
        text = self.simulated_text or SIMULATED_TEXT
        size = 9.0
        while size > 6 and self.get_string_width(text) > self.w - 2 * MARGIN - 2:
            size -= 0.5
            self.set_font("DejaVu", "B", size)
        self.cell(self.w - 2 * MARGIN, SIM_BAND - 2, text, align="C", fill=True)
        self.set_text_color(0)
        self.set_xy(MARGIN, self.t_margin)

    def footer(self) -> None:
        self.set_y(-MARGIN - 3)
        self.set_font("DejaVu", "", 7)
        self.set_text_color(110)
        self.set_draw_color(180)
        self.line(MARGIN, self.get_y(), self.w - MARGIN, self.get_y())
        self.cell(0, 4, self.trace, align="C", new_x="LMARGIN", new_y="NEXT")
        self.cell(0, 4, f"{self.report_title}  \u2014  page {self.page_no()} of {{nb}}",
                  align="C")
        self.set_text_color(0)


def _space_left(doc: FPDF) -> float:
    return doc.page_break_trigger - doc.get_y()


#: the report's formula notation: plain text -> (base, subscript) segments (the PDF draws the
#: subscript lowered and smaller: no literal underscore on the page)
NOTATION = {
    "\u03b4p_without": ("\u03b4p", "without"), "\u03b4p_with": ("\u03b4p", "with"),
    "K_X": ("K", "X"), "K_C": ("K", "C"), "K_\u03b8": ("K", "\u03b8"), "J_N": ("J", "N"),
    "\u03ba_F": ("\u03ba", "F"), "k_ref": ("k", "ref"),
}
_NOTATION_RE = re.compile("|".join(re.escape(k) for k in NOTATION))


def _segments(text: str) -> list[tuple[str, bool]]:
    """``text`` as (piece, subscript) segments."""
    out, pos = [], 0
    for m in _NOTATION_RE.finditer(text):
        base, sub = NOTATION[m.group(0)]
        out += [(text[pos:m.start()] + base, False), (sub, True)]
        pos = m.end()
    out.append((text[pos:], False))
    return [(t, s) for t, s in out if t]


def has_notation(text: str) -> bool:
    return bool(_NOTATION_RE.search(text))


def _write_rich(doc: FPDF, text: str, h: float, pad: float = 0.0) -> None:
    """Flowing text with the notation's subscripts, from the left margin (+ ``pad``)."""
    margin = doc.l_margin, doc.r_margin
    doc.set_left_margin(margin[0] + pad)
    doc.set_right_margin(margin[1] + pad)
    doc.set_x(doc.l_margin)
    for piece, sub in _segments(text):
        doc.char_vpos = "SUB" if sub else "LINE"
        doc.write(h, piece)
    doc.char_vpos = "LINE"
    doc.ln(h)
    doc.set_left_margin(margin[0])
    doc.set_right_margin(margin[1])
    doc.set_x(margin[0])


def _text(doc: FPDF, text: str, h: float, fill: bool = False, pad: float = 0.0) -> None:
    """A left-aligned paragraph: one multi_cell, or flowing segments when it holds the
    formula notation (with its tinted box measured first when ``fill``)."""
    if not has_notation(text):
        doc.multi_cell(0, h, text, fill=fill, new_x="LMARGIN", new_y="NEXT", padding=pad,
                       align="L")
        return
    if fill:
        y0 = doc.get_y()
        with doc.offset_rendering() as dummy:
            dummy.set_y(y0 + pad)
            _write_rich(dummy, text, h, pad)
        if not dummy.page_break_triggered:
            doc.rect(doc.l_margin, y0, doc.epw, dummy.get_y() - y0 + pad, style="F")
    doc.set_y(doc.get_y() + pad)
    _write_rich(doc, text, h, pad)
    doc.set_y(doc.get_y() + pad)


def _paragraph(doc: _Doc, p: Paragraph) -> None:
    if p.kind == "heading":
        if _space_left(doc) < KEEP_WITH_HEADING:
            doc.add_page()
        doc.start_section(p.text, level=1)
        doc.set_font("DejaVu", "B", 11)
        doc.multi_cell(0, 6, p.text, new_x="LMARGIN", new_y="NEXT")
        doc.ln(1)
        return
    bold = p.kind in ("facts", "verdict", "refusal")
    doc.set_font("DejaVu", "B" if bold else "", 9.5 if bold else 9)
    fill = p.kind in FILL
    if fill:
        doc.set_fill_color(*FILL[p.kind])
    if p.kind == "refusal":
        doc.set_text_color(176, 0, 0)
    _text(doc, p.text, 4.6, fill=fill, pad=1.2)
    doc.set_text_color(0)
    doc.ln(2)


def _widths(t: Table, total: float) -> list[float]:
    """Column widths (mm) summing to ``total``: the table's relative widths, else by the
    longest text of each column."""
    rel = list(t.widths) if t.widths else [
        max(len(c), *(len(r[i]) for r in t.rows), 3) for i, c in enumerate(t.columns)]
    return [total * w / sum(rel) for w in rel]


LINE_HEIGHT = 4.2  # mm, one line of text in a table cell
PAD = 0.5  # mm, inside each table cell, above and below the text
INSET = 1.1  # mm, left and right of the text in each cell (a text column beside numbers)
ROW_HEIGHT = LINE_HEIGHT + 2 * PAD  # mm, one line of a table row with its padding


def _table_height(t: Table) -> float:
    """Rough height (mm) of a table with its title, header and caption."""
    caption_lines = -(-len(t.caption) // 140) if t.caption else 0
    return 7 + 2.5 * ROW_HEIGHT + ROW_HEIGHT * len(t.rows) + 4 * caption_lines


def _lines(doc: _Doc, cells: list[str], widths: list[float]) -> list[list[str]]:
    """Each cell's text as the lines it takes in the current font: itself when it fits
    (one width measurement), else as fpdf's line breaking splits it (a dry run of
    multi_cell)."""
    out = []
    for text, w in zip(cells, widths, strict=True):
        if doc.get_string_width(text) <= w - 2 * INSET - 0.01:
            out.append([text])
        else:
            out.append(doc.multi_cell(w, LINE_HEIGHT, text, padding=(0, INSET), dry_run=True,
                                      output="LINES"))
    return out


def _row(doc: _Doc, cells: list[str], widths: list[float], align: list[str],
         fill: bool, min_height: float = 0.0) -> None:
    """One framed table row at the current y, every cell as high as the row's tallest and
    its text centred vertically: a one-line cell is one ``cell``, a wrapped one a frame and
    one ``cell`` per line. Starts a new page (repeating the header) when the row does not fit."""
    lines = _lines(doc, cells, widths)
    h = max(max(map(len, lines)) * LINE_HEIGHT + 2 * PAD, min_height)
    if doc.get_y() + h > doc.page_break_trigger and doc.table_header is not None:
        doc.add_page()
        header, doc.table_header = doc.table_header, None
        header()
        doc.table_header = header
    x0, y0 = doc.l_margin, doc.get_y()
    x = x0
    for cell_lines, w, a in zip(lines, widths, align, strict=True):
        doc.set_xy(x, y0)
        if len(cell_lines) == 1:
            doc.cell(w, h, cell_lines[0], border=1, align=a, fill=fill)
        else:  # the frame, then the lines as broken above, centred vertically
            doc.rect(x, y0, w, h, style="DF" if fill else "D")
            y = y0 + (h - len(cell_lines) * LINE_HEIGHT) / 2
            for text in cell_lines:
                doc.set_xy(x, y)
                doc.cell(w, LINE_HEIGHT, text, align=a)
                y += LINE_HEIGHT
        x += w
    doc.set_xy(x0, y0 + h)


def _table(doc: _Doc, t: Table) -> None:
    """A framed table: bold header on a tinted row (repeated after a page break), marked
    rows tinted, numeric columns right-aligned, long texts wrapped within their column."""
    need = _table_height(t)
    usable = doc.page_break_trigger - doc.t_margin - 20
    space = _space_left(doc)
    # rows of one line that would fit here: a split leaving one or two rows alone on the
    # next page starts the table there instead
    fit = int((space - 7 - 2.5 * ROW_HEIGHT) // ROW_HEIGHT)
    widow = need > space and 0 < len(t.rows) - fit <= 2
    if widow or space < (need if need < usable else 25 + 4 * ROW_HEIGHT):
        doc.add_page()
    doc.start_section(t.title.replace("_", ""), level=1)
    doc.set_font("DejaVu", "B", 10)
    _text(doc, t.title, 5.5)
    size = 7.5 if len(t.columns) > 7 else 8.5
    widths = _widths(t, doc.epw)
    align = ["R" if a == "right" else "L" for a in t.alignment()]
    body_font = "DejaVuMono" if t.mono else "DejaVu"
    doc.set_draw_color(150)
    margin, doc.c_margin = doc.c_margin, INSET  # the text's inset in one-line cells

    def header() -> None:
        doc.set_font("DejaVu", "B", size)
        doc.set_fill_color(*HEAD)
        _row(doc, t.columns, widths, align, fill=True)
        doc.set_font(body_font, "", size)
        doc.set_fill_color(*MARK)

    header()
    doc.table_header = header
    for cells, mark in zip(t.rows, t.marked, strict=True):
        _row(doc, cells, widths, align, fill=mark, min_height=10.0 if t.tall else 0.0)
    doc.table_header = None
    doc.c_margin = margin
    if t.caption:
        doc.set_font("DejaVu", "", 7.5)
        doc.set_text_color(80)
        _text(doc, t.caption, 3.8)
        doc.set_text_color(0)
    doc.ln(3)


def _figure(doc: _Doc, f: Figure) -> None:
    h = FIGURE_WIDTH * f.height / f.width
    if _space_left(doc) < h + 10:
        doc.add_page()
    x = (doc.w - FIGURE_WIDTH) / 2
    from analysis.report.pdf_png import place_png

    # the PNG's own compressed data, not decoded and re-encoded by fpdf2
    doc.image(place_png(doc, f.png), x=x, y=doc.get_y(), w=FIGURE_WIDTH, h=h)
    doc.set_y(doc.get_y() + h + 1)
    doc.set_font("DejaVu", "", 7.5)
    doc.set_text_color(80)
    _text(doc, f.caption, 3.8)
    doc.set_text_color(0)
    doc.ln(3)


def _block_height(doc: _Doc, block) -> float:
    """Rough height (mm) a block needs on its page to start there: a table that fits on a
    page whole, else its first rows; a figure with its caption; a few lines of text."""
    usable = doc.page_break_trigger - doc.t_margin - 20
    if isinstance(block, Table):
        need = _table_height(block)
        return need if need < usable else 25 + 4 * ROW_HEIGHT
    if isinstance(block, Figure):
        return FIGURE_WIDTH * block.height / block.width + 12
    return 15.0


def render_pdf(report: Report) -> bytes:
    """The report as PDF bytes: page 1 opens with the title and the result block; every
    page carries the report ID, date and software in its footer (and the SIMULATED DATA
    band at its top when the data are simulated)."""
    from analysis.report.html import trace_text

    doc = _Doc(report.title, report.simulated, trace_text(report), report.simulated_text)
    doc.add_page()
    doc.set_font("DejaVu", "B", 17)
    doc.multi_cell(0, 8, report.title, new_x="LMARGIN", new_y="NEXT")
    doc.set_font("DejaVu", "", 9)
    doc.set_text_color(100)
    doc.multi_cell(0, 5, report.subtitle, new_x="LMARGIN", new_y="NEXT")
    doc.set_text_color(0)
    doc.ln(2)
    for i, section in enumerate(report.sections):
        # the heading stays with its first block (a table kept whole, a figure)
        first = _block_height(doc, section.blocks[0]) if section.blocks else 0.0
        if i and _space_left(doc) < max(KEEP_WITH_HEADING, 12 + first):
            doc.add_page()
        heading = f"{i + 1}. {section.title}"
        doc.start_section(heading.replace("_", ""), level=0)
        doc.set_font("DejaVu", "B", 14)
        doc.set_draw_color(51, 102, 204)
        if has_notation(heading):
            _text(doc, heading, 8)
            doc.line(doc.l_margin, doc.get_y(), doc.w - doc.r_margin, doc.get_y())
        else:
            doc.cell(0, 8, heading, border="B", new_x="LMARGIN", new_y="NEXT")
        doc.ln(3)
        for block in section.blocks:
            if isinstance(block, Paragraph):
                _paragraph(doc, block)
            elif isinstance(block, Table):
                _table(doc, block)
            else:
                _figure(doc, block)
        doc.ln(3)
    return bytes(doc.output())
