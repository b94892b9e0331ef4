"""The command functions hold no job logic: they parse, call their job, and present.

Checked on the source (ast): each job's command module imports its job module
and calls its ``run``; it writes no file itself (no output_files helper, no
``open``), keeps no memory tricks (gc), imports from analysis/ only what it
presents with, and no function of it is longer than a face needs.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

COMMANDS = Path(__file__).parents[2] / "campaign" / "cli" / "commands"
JOBS = ("plan", "acquire", "analyze", "stiffness", "maps", "robustness", "compensate",
        "compare", "place", "robots", "demo", "lab", "export")
#: what a face may import from analysis/: its error class and presentation helpers
PRESENTATION = {"analysis.errors", "analysis.report.formatting",
                "analysis.identification.compare.comparison"}  # level_text: the verdict's wording
#: names a face must not use: file writing and the heap tricks belong to the job
FORBIDDEN = {"write_text", "write_bytes", "replacing", "make_dir", "replaced_dir",
             "created_dir", "check_output_dir", "save_figure", "open", "freeze", "unfreeze"}
#: lines of a function's body (after its docstring); ``register`` wraps the command
#: function with its typer signature and is measured by that function
MAX_BODY_LINES = 35


def _tree(job: str) -> ast.Module:
    return ast.parse((COMMANDS / f"{job}.py").read_text())


def _body_lines(node: ast.FunctionDef) -> int:
    body = node.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]
    return 0 if not body else body[-1].end_lineno - body[0].lineno + 1


def test_every_job_has_its_module():
    jobs = Path(__file__).parents[2] / "campaign" / "jobs"
    for job in JOBS:
        tree = ast.parse((jobs / f"{job}.py").read_text())
        names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
        assert "run" in names, job


@pytest.mark.parametrize("job", JOBS)
def test_command_calls_its_job(job):
    tree = _tree(job)
    imports = [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    assert any(n.module == f"campaign.jobs.{job}" and "run" in {a.name for a in n.names}
               for n in imports), f"campaign/cli/commands/{job}.py does not call its job's run"
    calls = {n.func.id for n in ast.walk(tree) if isinstance(n, ast.Call)
             and isinstance(n.func, ast.Name)}
    assert "run" in calls


@pytest.mark.parametrize("job", JOBS)
def test_command_holds_no_job_logic(job):
    tree = _tree(job)
    for n in ast.walk(tree):
        if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("analysis"):
            assert n.module in PRESENTATION, f"{job}: imports {n.module}"
        if isinstance(n, ast.Import):
            assert all(a.name != "gc" for a in n.names), f"{job}: gc belongs to the job"
        used = n.id if isinstance(n, ast.Name) else n.attr if isinstance(n, ast.Attribute) \
            else None
        assert used not in FORBIDDEN, f"{job}: uses {used} (line {n.lineno})"
        if isinstance(n, ast.FunctionDef) and n.name != "register":
            assert _body_lines(n) <= MAX_BODY_LINES, \
                f"{job}: {n.name} has {_body_lines(n)} lines"
