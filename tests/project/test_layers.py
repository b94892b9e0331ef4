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
    """Every module ``path`` (a file of this repository) imports, at the top or inside
    functions (relative imports resolved against its package)."""
    return _modules_of(path, ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1]))


def _modules_of(path: Path, package: str) -> set[str]:
    """Every module the Python file ``path`` imports, relative imports resolved against
    ``package`` (dotted name of the package the file sits in)."""
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


#: the packages of the mathematics: none may import the report's presentation
MATHEMATICS = ("identification", "model", "kinetostatics")


def test_the_mathematics_imports_nothing_from_the_report():
    """No module under analysis/identification, analysis/model or analysis/kinetostatics
    imports ``analysis.report`` (at the top or inside a function, absolute or relative):
    number formats they need come from :mod:`analysis.text_format`. No exceptions."""
    offenders = {}
    for package in MATHEMATICS:
        paths = sorted((ROOT / "analysis" / package).rglob("*.py"))
        assert paths, package
        for path in paths:
            bad = {m for m in _imported_modules(path)
                   if m == "analysis.report" or m.startswith("analysis.report.")}
            if bad:
                offenders[str(path.relative_to(ROOT))] = sorted(bad)
    assert offenders == {}


def test_the_import_reader_sees_a_relative_import_of_the_report(tmp_path):
    """The check above can fail: a relative ``from ...report import x`` inside a function
    of analysis/identification/checks/ resolves to ``analysis.report``."""
    probe = tmp_path / "probe.py"
    probe.write_text("def f():\n    from ...report.formatting import level\n")
    modules = _modules_of(probe, "analysis.identification.checks")
    assert {"analysis.report.formatting", "analysis.report.formatting.level"} <= modules


def _string_lists(path: Path):
    """(line, set of strings) of every tuple, list, set or Literal[...] of two or more
    string constants in ``path``."""
    for node in ast.walk(ast.parse(path.read_text())):
        elts = getattr(node, "elts", None)
        if isinstance(node, (ast.Tuple, ast.List, ast.Set)) and elts and len(elts) >= 2 \
                and all(isinstance(e, ast.Constant) and isinstance(e.value, str) for e in elts):
            yield node.lineno, {e.value for e in elts}


#: the lists of :mod:`analysis.choices`, each recognised by two of its names
CHOICE_LISTS = {"estimators": {"ols", "wls"}, "robust modes": {"huber", "tukey"},
                "geometry conventions": {"standard_dh", "modified_dh"}}


def test_every_list_of_choices_is_spelled_once():
    """Estimators, robust modes and geometry conventions are listed in analysis/choices.py
    only; code elsewhere derives its lists (enums, Literal types, checks, messages) from it."""
    from analysis import choices

    assert choices.METHODS == ("ols", "wls", "exact")
    assert set(choices.LINEARISED_METHODS) < set(choices.METHODS)
    assert choices.DEFAULT_METHOD in choices.METHODS
    assert choices.ROBUST_MODES[0] == "none"
    copies = []
    for package in ("analysis", "campaign", "drivers"):
        for path in sorted((ROOT / package).rglob("*.py")):
            if path == ROOT / "analysis" / "choices.py":
                continue
            for line, values in _string_lists(path):
                copies += [f"{path.relative_to(ROOT)}:{line}: {what}"
                           for what, names in CHOICE_LISTS.items() if names <= values]
    assert copies == []


def test_the_page_offers_the_choices_of_the_api():
    """The page's menus of estimators and robust modes are filled from the API's OpenAPI
    document, not typed into the HTML."""
    html = (ROOT / "campaign" / "web" / "static" / "index.html").read_text()
    for name in ("ols", "wls", "huber", "tukey"):
        assert f">{name}<" not in html and f'value="{name}"' not in html, name


def test_the_options_enums_are_the_choices():
    from analysis import choices
    from analysis.identification.estimators.registry import GAUSSIAN, ROBUST
    from campaign.jobs.choices import DEFAULT_METHOD, Method, Robust

    assert tuple(Method) == choices.METHODS and tuple(Robust) == choices.ROBUST_MODES
    assert DEFAULT_METHOD == choices.DEFAULT_METHOD
    assert tuple(GAUSSIAN) == choices.METHODS
    assert ("none", *ROBUST) == choices.ROBUST_MODES
