"""The ``campaign`` command line, one face of the application layer.

:mod:`campaign.cli.app` builds the typer app and maps errors to exit statuses;
:mod:`campaign.cli.terminal` holds what the commands share (``--json``, panels,
wrapping); :mod:`campaign.cli.commands` has one module per command, each a thin
face over its job in :mod:`campaign.jobs` (the web API in :mod:`campaign.web` is
the other face). :func:`main` is the console script ``campaign`` and
``python -m campaign``; it imports the app only when called, so that importing
this package (for :mod:`campaign.cli.terminal`) costs nothing.
"""

from __future__ import annotations


def main(argv: list[str] | None = None) -> int:
    """Run ``campaign`` with ``argv`` (default: the process's arguments); the exit status."""
    from campaign.cli.app import main as run_app

    return run_app(argv)
