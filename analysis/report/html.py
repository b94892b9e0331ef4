"""The report as one self-contained HTML file: inline CSS, plots as base64 PNG, no scripts."""

from __future__ import annotations

import base64
from html import escape

from analysis.report.document import Figure, Paragraph, Report, Section, Table

CSS = """
body { font-family: "DejaVu Sans", Helvetica, Arial, sans-serif; margin: 2em auto;
       max-width: 62em; color: #222; line-height: 1.4; padding: 0 1em; }
h1 { font-size: 1.6em; margin-bottom: 0.1em; } h2 { border-bottom: 2px solid #36c;
     padding-bottom: 0.2em; margin-top: 2em; } h3 { font-size: 1.05em; margin: 1.2em 0 0.4em; }
.subtitle { color: #666; margin-top: 0; }
.warning { background: #fff3cd; border-left: 4px solid #d90; padding: 0.5em 0.8em; }
.note { background: #eef3fb; border-left: 4px solid #36c; padding: 0.5em 0.8em; }
table { border-collapse: collapse; margin: 0.4em 0 0.3em; font-size: 0.88em; }
th, td { border: 1px solid #bbb; padding: 0.25em 0.55em; }
th { background: #e8ecf4; } .r { text-align: right; } .l { text-align: left; }
tr.marked td { background: #fde2e1; font-weight: bold; }
table.mono td { font-family: "DejaVu Sans Mono", monospace; }
.caption { color: #555; font-size: 0.85em; margin: 0 0 1em; }
figure { margin: 1em 0; } figure img { max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { color: #555; font-size: 0.85em; }
nav ol { columns: 2; }
.scroll { overflow-x: auto; max-width: 100%; -webkit-overflow-scrolling: touch; }
.facts { font-weight: bold; margin: 0.6em 0 0.3em; }
.verdict { background: #e6f4ea; border-left: 4px solid #2a7; padding: 0.5em 0.8em;
           font-weight: bold; }
.refusal { background: #fde2e1; border-left: 4px solid #c00; color: #b00; padding: 0.5em 0.8em;
           font-weight: bold; }
.lab-banner { position: sticky; top: 0; z-index: 10; background: #c00; color: #fff;
             font-weight: bold; text-align: center; padding: 0.35em 0.5em;
             letter-spacing: 0.05em; margin: 0 -1em; }
.trace { color: #555; font-size: 0.8em; margin: 0.2em 0; }
table.tall td { height: 2.4em; }
@media (max-width: 600px) { body { margin: 0.5em auto; } nav ol { columns: 1; }
  table { font-size: 0.78em; } }
@media print {
  body { max-width: none; margin: 0; padding: 0; font-size: 10pt; }
  .lab-banner { position: fixed; top: 0; left: 0; right: 0; margin: 0; }
  body.sim { padding-top: 2.2em; }
  nav { display: none; }
  h2, h3 { break-after: avoid; page-break-after: avoid; }
  table, figure, .caption, tr { break-inside: avoid; page-break-inside: avoid; }
  thead { display: table-header-group; }
  .scroll { overflow: visible; }
  figure img { max-width: 100%; }
}
"""


#: plain-text notation of the report model -> HTML (subscripts, superscripts, italics)
NOTATION = [
    ("K_X\u207b\u00b9", "<i>K</i><sub>X</sub><sup>\u22121</sup>"),
    ("J\u207b\u1d40", "<i>J</i><sup>\u2212T</sup>"),
    ("J\u207b\u00b9", "<i>J</i><sup>\u22121</sup>"),
    ("K_X", "<i>K</i><sub>X</sub>"), ("K_C", "<i>K</i><sub>C</sub>"),
    ("K_\u03b8", "<i>K</i><sub>\u03b8</sub>"), ("J_N", "<i>J</i><sub>N</sub>"),
    ("\u03ba_F", "<i>\u03ba</i><sub>F</sub>"),
    ("\u03b4p_without", "\u03b4<i>p</i><sub>without</sub>"),
    ("\u03b4p_with", "\u03b4<i>p</i><sub>with</sub>"),
]


def _math(text: str) -> str:
    """Escaped ``text`` with the report's formula notation as HTML (K_X -> K<sub>X</sub>).

    Headings keep the plain text (anchors, navigation and the PDF's outline)."""
    out = escape(text)
    for plain, html in NOTATION:
        out = out.replace(escape(plain), html)
    return out


def _anchor(title: str) -> str:
    return "".join(c if c.isalnum() else "-" for c in title.lower()).strip("-")


def _paragraph(p: Paragraph) -> str:
    if p.kind == "heading":
        return f"<h3>{escape(p.text)}</h3>"
    cls = (f' class="{p.kind}"' if p.kind in ("note", "warning", "facts", "verdict", "refusal")
           else "")
    return f"<p{cls}>{_math(p.text)}</p>"


def _table(t: Table) -> str:
    align = ["r" if a == "right" else "l" for a in t.alignment()]
    head = "".join(f'<th class="{a}">{_math(c)}</th>' for c, a in zip(t.columns, align,
                                                                         strict=True))
    body = []
    for row, mark in zip(t.rows, t.marked, strict=True):
        cells = "".join(f'<td class="{a}">{escape(c)}</td>' for c, a in zip(row, align,
                                                                             strict=True))
        body.append(f'<tr class="marked">{cells}</tr>' if mark else f"<tr>{cells}</tr>")
    names = [n for n, on in (("mono", t.mono), ("tall", t.tall)) if on]
    cls = f' class="{" ".join(names)}"' if names else ""
    caption = f'<p class="caption">{_math(t.caption)}</p>' if t.caption else ""
    return (f'<h3>{escape(t.title)}</h3><div class="scroll"><table{cls}><thead><tr>{head}'
            f"</tr></thead><tbody>{''.join(body)}</tbody></table></div>{caption}")


def _figure(f: Figure) -> str:
    data = base64.b64encode(f.png).decode("ascii")
    return (f'<figure id="fig-{escape(f.name)}"><img src="data:image/png;base64,{data}" '
            f'width="{f.width}" height="{f.height}" alt="{escape(f.caption)}">'
            f"<figcaption>{_math(f.caption)}</figcaption></figure>")


def _section(s: Section) -> str:
    parts = [f'<section id="{_anchor(s.title)}"><h2>{escape(s.title)}</h2>']
    for block in s.blocks:
        if isinstance(block, Paragraph):
            parts.append(_paragraph(block))
        elif isinstance(block, Table):
            parts.append(_table(block))
        else:
            parts.append(_figure(block))
    parts.append("</section>")
    return "\n".join(parts)


SIMULATED_TEXT = ("SIMULATED DATA \u2014 this run came from the simulated lab, not from a "
                  "measurement of a real robot")


def trace_text(report: Report) -> str:
    """'Report ID ... · generated ... · software ...' (the PDF's footer, the HTML's head)."""
    t = report.trace
    parts = [f"Report ID {t.report_id}" if t.report_id else "",
             f"generated {t.generated_utc}" if t.generated_utc else "", t.software]
    return " \u00b7 ".join(p for p in parts if p)


def render_html(report: Report) -> str:
    """The report as an HTML document (UTF-8 text): the result block first, the contents
    after the summary; a SIMULATED DATA banner on every screen (sticky) and printed page
    (fixed) when the data are simulated."""
    nav = "".join(f'<li><a href="#{_anchor(s.title)}">{escape(s.title)}</a></li>'
                  for s in report.sections)
    sections = [_section(s) for s in report.sections]
    nav_html = f"<nav><h3>Contents</h3><ol>{nav}</ol></nav>"
    body = "\n".join(sections[:1] + [nav_html] + sections[1:])
    sim = (f'<div class="lab-banner" role="note">'
           f'{escape(report.simulated_text or SIMULATED_TEXT)}</div>'
           if report.simulated else "")
    trace = escape(trace_text(report))
    body_class = ' class="sim"' if report.simulated else ""
    return (
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">"
        f"<title>{escape(report.title)}</title><style>{CSS}</style></head>"
        f"<body{body_class}>{sim}"
        f"<h1>{escape(report.title)}</h1><p class=\"subtitle\">{escape(report.subtitle)}</p>"
        f"<p class=\"trace\">{trace}</p>\n{body}\n"
        f"<footer><p class=\"trace\">{trace}</p></footer></body></html>\n"
    )
