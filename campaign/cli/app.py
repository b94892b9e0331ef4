"""The ``campaign`` command line (typer).

Every sub-command lives in its own module of :mod:`campaign.cli.commands` and
registers itself with ``register(app)``. The commands of :data:`LAZY_COMMANDS`
are imported only when invoked (``campaign --help`` lists them from the table),
so that a command pays only for its own imports; a module not in the table is
imported when the app is built. Bad input raises
:class:`analysis.errors.InputError`; :func:`main` prints it as one line on
stderr and exits with status 2, never with a traceback. So does a wrench the
nonlinear equilibrium cannot carry (:class:`EquilibriumError`). A file system that
refuses a write (:class:`OSError`: disk full, read-only, permissions) is one line
and exit status 1.
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import typer
from typer.core import TyperCommand, TyperGroup

import campaign.cli.commands
from analysis.errors import InputError

#: Commands imported when invoked: name -> (module of :mod:`campaign.cli.commands`, the line
#: ``campaign --help`` shows = first paragraph of the command's docstring; a test checks
#: both). A new command module works without an entry here, imported at every start.
LAZY_COMMANDS: dict[str, tuple[str, str]] = {
    "acquire": ("acquire", "Measure every planned test: approach, settle, tare, unloaded pose, "
                "load, wrench and loaded pose, unload, unloaded pose again; every reading on "
                "disk before the next motion."),
    "analyze": ("analyze", "Identify joint stiffness from a run or a CSV file; write "
                "results.json and the report."),
    "compare": ("compare", "Per joint: k_B - k_A with its interval, z score and verdict."),
    "compensate": ("compensate", "Predict the deflection of P along a path and compute the "
                   "compensated joints."),
    "demo": ("demo", "Plan, acquire on the simulated lab and analyse the KR240-2 campaign "
             "(Dumas et al. 2011)."),
    "export": ("export", "Write the robot as a simulator file: MJCF, URDF or SDF with its joint "
               "springs."),
    "gui": ("gui", "Start the GUI on a local web server and print its URL with the access "
            "token."),
    "history": ("history", "The fleet ledger: every campaign of every robot, trends with "
                "intervals, and an alarm when a joint loses stiffness."),
    "lab": ("lab", "Start fake instruments on loopback that speak the real protocols."),
    "maps": ("maps", "Maps like the paper's Figs. 3 and 5: data table and PNG plots."),
    "place": ("place", "Search the workpiece placement and tool angles that minimise P's "
              "deflection."),
    "plan": ("plan", "Plan the tests: candidate poses in the zones, thresholds, optimal "
             "design."),
    "robots": ("robots", "List built-in robot models, or show one model's joints, limits and "
               "sources."),
    "robustness": ("robustness", "Spread of the identified joint stiffness against the number "
                   "of tests."),
    "stiffness": ("stiffness", "Kinematic Jacobian, K_C (eq. 8), K_X with and without K_C "
                  "(eqs. 6, 12), deflection."),
}


def load_command(name: str, module: str) -> TyperCommand:
    """The click command ``name`` registered by ``campaign.cli.commands.<module>``."""
    sub = typer.Typer(add_completion=False, pretty_exceptions_enable=False)

    @sub.callback()
    def _group() -> None:
        """A callback keeps the app a group even with one command, so it keeps its name."""

    importlib.import_module(f"campaign.cli.commands.{module}").register(sub)
    command = typer.main.get_command(sub).commands.get(name)  # type: ignore[attr-defined]
    if command is None:
        raise LookupError(f"campaign.cli.commands.{module} does not register a command {name!r}; "
                          "fix LAZY_COMMANDS in campaign/cli/app.py")
    return escape_help(command)


def escape_help(command):
    """``command`` with rich markup escaped in its help and its parameters' help, once.

    typer renders help texts as rich markup, which would read the protocol's
    ``[tool]`` or ``[fake_lab]`` as style tags and drop them from ``--help``; a
    help text here is plain text, so every ``[`` is escaped. Returns ``command``.
    """
    from rich.markup import escape

    if getattr(command, "_help_escaped", False):
        return command
    if command.help:
        command.help = escape(command.help)
    for param in command.params:
        if getattr(param, "help", None):
            param.help = escape(param.help)
    command._help_escaped = True
    return command


class _Placeholder(TyperCommand):
    """A lazy command as ``--help`` lists it: name and one-line help, no import."""

    def __init__(self, name: str, module: str, help_line: str) -> None:
        super().__init__(name=name, help=help_line)
        self.module = module


class _LazyGroup(TyperGroup):
    """Root group: lists placeholders, swaps in the real command when one is invoked."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        for name, (module, help_line) in LAZY_COMMANDS.items():
            # a command registered eagerly under the same name wins
            self.commands.setdefault(name, _Placeholder(name, module, help_line))
        self.commands = {name: escape_help(command)
                         for name, command in sorted(self.commands.items())}

    def resolve_command(self, ctx, args):
        placeholder = self.commands.get(args[0]) if args else None
        if isinstance(placeholder, _Placeholder):
            self.commands[args[0]] = load_command(args[0], placeholder.module)
        return super().resolve_command(ctx, args)


def build_app() -> typer.Typer:
    """The typer app: :data:`LAZY_COMMANDS`, plus every other module of
    :mod:`campaign.cli.commands`."""
    app = typer.Typer(
        name="campaign",
        help="Plan, run and analyse joint-stiffness identification campaigns of serial robots.",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
        cls=_LazyGroup,
    )

    @app.callback()
    def _root(
        version: bool = typer.Option(False, "--version", is_eager=True,
                                     callback=_print_version,
                                     help="Print the version and exit."),
    ) -> None:
        """Plan, run and analyse joint-stiffness identification campaigns of serial robots."""

    lazy_modules = {module for module, _ in LAZY_COMMANDS.values()}
    for info in sorted(pkgutil.iter_modules(campaign.cli.commands.__path__), key=lambda m: m.name):
        if info.name in lazy_modules:
            continue
        module = importlib.import_module(f"campaign.cli.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(app)
    return app


def _print_version(value: bool) -> None:
    """``campaign --version``: the installed package's version."""
    if not value:
        return
    import importlib.metadata

    try:
        version = importlib.metadata.version("robot-stiffness-campaign")
    except importlib.metadata.PackageNotFoundError:
        version = "unknown (not installed)"
    typer.echo(f"campaign (robot-stiffness-campaign) {version}")
    raise typer.Exit(0)


def _is_equilibrium_error(err: Exception) -> bool:
    """True for the equilibrium solver's non-convergence (bad input, not a bug)."""
    from analysis.kinetostatics.equilibrium import EquilibriumError

    return isinstance(err, EquilibriumError)


def _error(text: str) -> None:
    """An error message on stderr: one line for logs and scripts; on a terminal, wrapped
    at word boundaries to its width (the terminal itself would cut words in two)."""
    import shutil

    from campaign.cli.terminal import wrap_text

    width = shutil.get_terminal_size().columns if sys.stderr.isatty() else None
    typer.echo(wrap_text(text, width), err=True)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit status."""
    app = build_app()
    try:
        # with standalone_mode=False, click returns the code of a typer.Exit instead of raising
        status = app(args=argv, standalone_mode=False)
        if isinstance(status, int) and status:
            return status
    except InputError as err:
        _error(f"error: {err}")
        return 2
    except typer.Abort:
        typer.echo("aborted", err=True)
        return 1
    except typer.Exit as ex:
        return int(ex.exit_code or 0)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        return 130
    except OSError as err:
        # the file system refused (disk full, read-only, permissions): a runtime failure,
        # one line naming the file, exit status 1
        where = f"{err.filename}: " if err.filename else ""
        typer.echo(f"error: {where}{err.strerror or err}", err=True)
        return 1
    except Exception as err:
        if type(err).__name__ == "EquilibriumError" and _is_equilibrium_error(err):
            _error(f"error: nonlinear equilibrium: {err}; reduce the wrench or check the "
                   "joint stiffness")
            return 2
        # Usage errors of the click layer under typer carry their own message and code.
        if hasattr(err, "show") and isinstance(getattr(err, "exit_code", None), int):
            err.show()
            return err.exit_code
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
