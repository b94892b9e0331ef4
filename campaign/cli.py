"""The ``campaign`` command line (typer).

Every sub-command lives in its own module of :mod:`campaign.commands` and
registers itself with ``register(app)``. Bad input raises
:class:`analysis.errors.InputError`; :func:`main` prints it as one line on
stderr and exits with status 2, never with a traceback. So does a wrench the
nonlinear equilibrium cannot carry (:class:`EquilibriumError`).
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import typer

import campaign.commands
from analysis.errors import InputError


def build_app() -> typer.Typer:
    """Create the typer app with every command module of :mod:`campaign.commands`."""
    app = typer.Typer(
        name="campaign",
        help="Plan, run and analyse joint-stiffness identification campaigns of serial robots.",
        no_args_is_help=True,
        add_completion=False,
        pretty_exceptions_enable=False,
    )

    @app.callback()
    def _root() -> None:
        """Plan, run and analyse joint-stiffness identification campaigns of serial robots."""

    for info in sorted(pkgutil.iter_modules(campaign.commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"campaign.commands.{info.name}")
        register = getattr(module, "register", None)
        if register is not None:
            register(app)
    return app


def _is_equilibrium_error(err: Exception) -> bool:
    """True for the equilibrium solver's non-convergence (bad input, not a bug)."""
    from analysis.kinetostatics.equilibrium import EquilibriumError

    return isinstance(err, EquilibriumError)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit status."""
    app = build_app()
    try:
        # with standalone_mode=False, click returns the code of a typer.Exit instead of raising
        status = app(args=argv, standalone_mode=False)
        if isinstance(status, int) and status:
            return status
    except InputError as err:
        typer.echo(f"error: {err}", err=True)
        return 2
    except typer.Abort:
        typer.echo("aborted", err=True)
        return 1
    except typer.Exit as ex:
        return int(ex.exit_code or 0)
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        return 130
    except Exception as err:
        if type(err).__name__ == "EquilibriumError" and _is_equilibrium_error(err):
            typer.echo(f"error: nonlinear equilibrium: {err}; reduce the wrench or check the "
                       "joint stiffness", err=True)
            return 2
        # Usage errors of the click layer under typer carry their own message and code.
        if hasattr(err, "show") and isinstance(getattr(err, "exit_code", None), int):
            err.show()
            return err.exit_code
        raise
    return 0


if __name__ == "__main__":
    sys.exit(main())
