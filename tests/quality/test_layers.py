"""The house's rules a newcomer relies on: every page of docs/ can be reached from the
README or the architecture page, and the identification's mathematics does not depend on
the report's presentation (static: the imports are read from the source, nothing run)."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _links(page: Path) -> set[str]:
    """The docs/ page names a Markdown page links to (``docs/x.md`` or ``x.md``)."""
    return {Path(target).name for target in re.findall(r"\]\(([^)#]+\.md)", page.read_text())}


def test_every_docs_page_is_linked_from_the_readme_or_the_architecture_page():
    linked = _links(ROOT / "README.md") | _links(ROOT / "docs" / "architecture.md")
    pages = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert {"architecture.md", "gui.md", "benchmarks.md", "jobs.md"} <= pages
    assert pages - linked == set(), f"docs pages no entry point links to: {pages - linked}"


def test_every_relative_link_of_the_readme_and_the_docs_resolves():
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for target in re.findall(r"\]\(([^)#:]+)(?:#[^)]*)?\)", page.read_text()):
            assert (page.parent / target).exists(), f"{page.name}: broken link {target}"


def test_the_readme_is_an_entry_point_of_at_most_200_lines():
    assert len((ROOT / "README.md").read_text().splitlines()) <= 200


def _imported_modules(path: Path) -> set[str]:
    """Every module ``path`` imports, at the top or inside functions (relative imports
    resolved against its package)."""
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            out.add(base)
            out.update(f"{base}.{a.name}" for a in node.names)
        elif isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
    return out


def test_the_identification_imports_nothing_from_the_report():
    offenders = {}
    for path in sorted((ROOT / "analysis" / "identification").rglob("*.py")):
        bad = {m for m in _imported_modules(path)
               if m == "analysis.report" or m.startswith("analysis.report.")}
        if bad:
            offenders[str(path.relative_to(ROOT))] = sorted(bad)
    assert offenders == {}
