"""Start-up hygiene of the ``campaign`` command line: which libraries a command imports.

Building the app (every ``campaign`` invocation, ``--help`` included) must not
import the heavy libraries; each command imports what it needs when it runs.
Each check runs in a fresh interpreter, so what is in ``sys.modules`` is what
that code path imported. Timing is measured by benchmarks/bench_startup.py.
"""

from __future__ import annotations

import importlib
import inspect
import json
import pkgutil
import subprocess
import sys

import typer
import typer.main

import campaign.cli.app as cli
import campaign.cli.commands

#: Libraries whose import costs tens to hundreds of ms of CPU each.
HEAVY = ("matplotlib", "scipy", "pandas", "pinocchio", "pyarrow", "dask")

PROBE = """
import json, sys
{code}
print("MODULES=" + json.dumps(sorted(m for m in sys.modules
                                      if m.split(".")[0] in {heavy!r} or m in {heavy!r})))
"""


def imported_after(code: str, heavy=HEAVY) -> tuple[list[str], str]:
    """(heavy modules in sys.modules after running ``code`` in a new interpreter, stdout)."""
    proc = subprocess.run([sys.executable, "-c", PROBE.format(code=code, heavy=tuple(heavy))],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    line = [s for s in proc.stdout.splitlines() if s.startswith("MODULES=")][-1]
    return json.loads(line.removeprefix("MODULES=")), proc.stdout


def top_level(modules: list[str]) -> set[str]:
    return {m.split(".")[0] for m in modules}


def command_modules() -> list[str]:
    return sorted(m.name for m in pkgutil.iter_modules(campaign.cli.commands.__path__))


def test_building_the_app_imports_no_heavy_library():
    found, out = imported_after(
        "import campaign.cli.app\n"
        "app = campaign.cli.app.build_app()\n"
        "import typer.main\n"
        "print('COMMANDS=' + ','.join(sorted(typer.main.get_command(app).commands)))\n")
    assert found == []
    # every module with register(app) took part: the check saw the whole command line
    commands = [s for s in out.splitlines() if s.startswith("COMMANDS=")][0]
    assert len(commands.removeprefix("COMMANDS=").split(",")) >= len(command_modules())


def test_no_command_module_imports_a_heavy_library_at_import_time():
    """Per module, so that a failure names the module to fix."""
    names = command_modules()
    assert {"analyze", "stiffness", "maps", "plan", "robots"} <= set(names)
    code = (
        "import importlib\n"
        f"for name in {names!r}:\n"
        "    importlib.import_module('campaign.cli.commands.' + name)\n"
        "    heavy = sorted({m.split('.')[0] for m in sys.modules} & set(" + repr(HEAVY) + "))\n"
        "    print('MODULE', name, ','.join(heavy))\n")
    _, out = imported_after(code)
    lines = [s.split(" ") for s in out.splitlines() if s.startswith("MODULE ")]
    assert [n for _, n, _ in lines] == names
    assert {n: h for _, n, h in lines if h} == {}


def test_help_lists_every_command_and_imports_no_lazy_command_module():
    lazy = sorted({module for module, _ in cli.LAZY_COMMANDS.values()})
    found, out = imported_after(
        "from campaign.cli import main\n"
        "status = main(['--help'])\n"
        "assert status == 0, status\n"
        f"print('LOADED=' + ','.join(m for m in {lazy!r} "
        "if 'campaign.cli.commands.' + m in sys.modules))\n")
    assert found == []
    assert [s for s in out.splitlines() if s.startswith("LOADED=")] == ["LOADED="]
    for name in command_modules():
        assert f" {name} " in out


def registered(module: str) -> dict:
    """{name: click command} that ``campaign.cli.commands.<module>`` registers."""
    app = typer.Typer()

    @app.callback()
    def _group() -> None:
        pass

    importlib.import_module(f"campaign.cli.commands.{module}").register(app)
    return typer.main.get_command(app).commands


def test_lazy_table_matches_what_the_modules_register():
    for name, (module, help_line) in cli.LAZY_COMMANDS.items():
        commands = registered(module)
        assert name in commands, f"campaign.cli.commands.{module} registers {sorted(commands)}"
        first = " ".join(inspect.cleandoc(commands[name].help or "").split("\n\n")[0].split())
        assert help_line == first, (
            f"campaign --help would show another text than `campaign {name} --help`: set "
            f"LAZY_COMMANDS[{name!r}] in campaign/cli/app.py to ({module!r}, {first!r})")


def test_a_module_missing_from_the_table_is_registered_at_start(monkeypatch, capsys):
    monkeypatch.delitem(cli.LAZY_COMMANDS, "robots")
    app = cli.build_app()
    group = typer.main.get_command(app)
    assert not isinstance(group.commands["robots"], cli._Placeholder)
    assert isinstance(group.commands["stiffness"], cli._Placeholder)
    assert cli.main(["robots"]) == 0
    assert "kr240-2" in capsys.readouterr().out


def test_invoking_a_lazy_command_runs_the_real_one(capsys):
    assert cli.main(["stiffness", "--robot", "kr240-2", "--q", "0,30,10,45,45,45",
                     "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert len(data["K_X"]) == 6 and data["robot"]
    # an error of the command's input still comes out as one line and status 2
    assert cli.main(["stiffness", "--robot", "kr240-2", "--q", "1,2"]) == 2
    assert capsys.readouterr().err.strip() == \
        "error: --q: expected 6 comma-separated numbers, got 2"


def test_stiffness_imports_pinocchio_but_not_scipy_pandas_matplotlib():
    found, out = imported_after(
        "from campaign.cli import main\n"
        "status = main(['stiffness', '--robot', 'kr240-2', '--q', '0,30,10,45,45,45', "
        "'--json'])\n"
        "assert status == 0, status\n"
        "print('LOADED=' + ','.join(sorted(m.rsplit('.', 1)[1] for m in sys.modules "
        "if m.startswith('campaign.cli.commands.'))))\n")
    assert top_level(found) == {"pinocchio"}
    # only the invoked command's module was imported
    assert [s for s in out.splitlines() if s.startswith("LOADED=")] == ["LOADED=stiffness"]
    # and it did the work: the nonlinear deflection is there and non-zero
    data = json.loads(out[: out.index("LOADED=")])
    assert any(abs(v) > 1e-6 for v in data["deflection_nonlinear_m_rad"][:3])


def test_plan_command_strategies_match_the_planner():
    from campaign.cli.terminal import Strategy
    from campaign.planning.planner import STRATEGIES

    # the CLI's enum is kept apart from the planner (which pulls in pandas) and must agree
    assert tuple(s.value for s in Strategy) == STRATEGIES


def test_no_command_help_imports_numpy_or_a_heavy_library():
    """``campaign <cmd> --help`` imports the command's module but neither numpy nor the heavy
    libraries; in one interpreter, in order, so the first command that does is the one named."""
    names = sorted(cli.LAZY_COMMANDS)
    assert len(names) >= len(command_modules())
    code = (
        "from campaign.cli import main\n"
        "import contextlib, io\n"
        f"for name in {names!r}:\n"
        "    with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "        status = main([name, '--help'])\n"
        "    assert status == 0 and 'Usage' in out.getvalue(), (name, status)\n"
        "    heavy = sorted({m.split('.')[0] for m in sys.modules} & set("
        + repr(("numpy", *HEAVY)) + "))\n"
        "    print('HELP', name, ','.join(heavy))\n")
    _, out = imported_after(code)
    lines = [s.split(" ") for s in out.splitlines() if s.startswith("HELP ")]
    assert [n for _, n, _ in lines] == names
    assert {n: h for _, n, h in lines if h} == {}
