"""The generated HTML report read back with html.parser, for the report tests."""

from __future__ import annotations

import base64
from html.parser import HTMLParser


class ReportPage(HTMLParser):
    """Visible text, h2 titles, tables (title = text of the preceding h3 -> rows of cells),
    the figures as (alt text, PNG bytes), and any reference to an external resource."""

    def __init__(self) -> None:
        super().__init__()
        self.text: list[str] = []
        self.h2: list[str] = []
        self.tables: dict[str, list[list[str]]] = {}
        self.figures: list[tuple[str, bytes]] = []
        self.images: list[str] = []
        self.external: list[str] = []
        self._heading: str | None = None
        self._title = ""
        self._row: list[str] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag in ("h2", "h3"):
            self._heading = tag
            if tag == "h3":
                self._title = ""
            else:
                self.h2.append("")
        if tag == "script":
            self.external.append("script")
        if tag == "link" or (tag in ("img", "iframe")
                             and not str(a.get("src", "")).startswith("data:")):
            self.external.append(f"{tag} {a}")
        if tag == "img":
            self.images.append(a["src"])
            if str(a["src"]).startswith("data:"):
                self.figures.append((a.get("alt", ""),
                                     base64.b64decode(a["src"].split(",", 1)[1])))
        if tag == "table":
            self.tables[self._title] = []
        if tag == "tr":
            self._row = []
        if tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if tag == self._heading:
            self._heading = None
        if tag in ("td", "th") and self._row is not None:
            self._row.append("".join(self._cell or []).strip())
            self._cell = None
        if tag == "tr" and self._row is not None:
            self.tables[self._title].append(self._row)
            self._row = None

    def handle_data(self, data):
        self.text.append(data)
        if self._heading == "h3":
            self._title += data.strip()
        elif self._heading == "h2":
            self.h2[-1] += data.strip()
        if self._cell is not None:
            self._cell.append(data)
