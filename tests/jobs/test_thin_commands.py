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


# ---- the web handlers (campaign/web): the other face over the same jobs ----

WEB = Path(__file__).parents[2] / "campaign" / "web"
#: the jobs that take seconds to minutes: the web runs them queued, in a process of their
#: own (campaign/web/job_tasks.py, through job_submit.submit), never in a request
LONG_JOBS = {"plan", "acquire", "analyze", "maps", "robustness", "compensate", "place", "demo"}
#: where a long job's ``run`` may be called from the web: the queue's tasks (job_tasks.py,
#: demo_api.demo_task), and the acquisition's dry run (it lists motions, nothing moves)
QUEUED_TASKS = {("job_tasks.py", job) for job in LONG_JOBS} | {
    ("demo_api.py", "demo"), ("acquire_api.py", "acquire")}
#: handlers that still run a long job in the request (moving them to the queue is pending)
LEFT_IN_REQUEST: set[tuple[str, str]] = set()
#: what a web handler may import from analysis/: errors, the named choices, the names of
#: robots, the verdict's wording and the report's number formats
WEB_PRESENTATION = {"analysis.errors", "analysis.choices", "analysis.file_errors",
                    "analysis.report.formatting",
                    "analysis.model.robot_spec", "analysis.model.robots",
                    "analysis.report.verdict", "analysis.kinetostatics.equilibrium"}
#: imports of analysis/ left in a handler (to move into its job)
LEFT_IMPORTS = {("sensitivity_api.py", "analysis.identification.noise")}


def _web_modules() -> list[Path]:
    return sorted(p for p in WEB.glob("*.py") if p.name != "__init__.py")


def _job_runs(tree: ast.Module) -> set[str]:
    """The jobs of :mod:`campaign.jobs` whose ``run`` (or ``run_*``) a module imports."""
    out = set()
    for n in ast.walk(tree):
        if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("campaign.jobs."):
            if any(a.name == "run" or a.name.startswith("run_") for a in n.names):
                out.add(n.module.split(".")[2])
    return out


def test_the_web_handlers_are_found():
    names = {p.name for p in _web_modules()}
    assert {"api_jobs.py", "plan_api.py", "job_tasks.py", "sensitivity_api.py"} <= names
    assert "analyze_api.py" not in names  # the in-process analyze route is gone


@pytest.mark.parametrize("path", _web_modules(), ids=lambda p: p.name)
def test_a_web_handler_runs_no_long_job_in_the_request(path):
    tree = ast.parse(path.read_text())
    for job in _job_runs(tree) & LONG_JOBS:
        assert (path.name, job) in QUEUED_TASKS | LEFT_IN_REQUEST, \
            f"campaign/web/{path.name} runs the {job} job in the server: queue it (job_submit)"


@pytest.mark.parametrize("path", _web_modules(), ids=lambda p: p.name)
def test_a_web_handler_holds_no_job_logic(path):
    tree = ast.parse(path.read_text())
    for n in ast.walk(tree):
        if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith("analysis"):
            assert n.module in WEB_PRESENTATION or (path.name, n.module) in LEFT_IMPORTS, \
                f"campaign/web/{path.name} imports {n.module}"
        if isinstance(n, ast.Import):
            assert all(a.name != "gc" for a in n.names), f"{path.name}: gc belongs to the job"


def test_the_lists_of_what_is_left_are_current():
    """An entry of LEFT_IN_REQUEST / LEFT_IMPORTS that no longer holds is removed."""
    for name, job in LEFT_IN_REQUEST:
        assert job in _job_runs(ast.parse((WEB / name).read_text())), (name, job)
    for name, module in LEFT_IMPORTS:
        tree = ast.parse((WEB / name).read_text())
        assert any(isinstance(n, ast.ImportFrom) and n.module == module
                   for n in ast.walk(tree)), (name, module)
