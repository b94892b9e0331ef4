"""What every ``campaign`` command shares: the choices (enums of :mod:`campaign.jobs.choices`),
``--json`` output, ``--force`` for output directories, progress of long stages.

Only the standard library, typer and rich at import time: every command module
is imported at start-up.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from campaign.jobs.choices import (  # noqa: F401 (the commands' choices, re-exported)
    DEFAULT_METHOD,
    DEFAULT_TRIALS,
    Covariance,
    Method,
    Objective,
    Program,
    Robust,
    RotationSource,
    SimFormat,
    Strategy,
    TableFormat,
    WrenchFrame,
    json_ready,
)
from campaign.text_wrap import print_wrapped, wrap_text  # noqa: F401 (re-exported)

#: Panels of ``--help`` shared by the commands: options grouped in panels keep each
#: panel's columns narrow, so option names stay whole and descriptions readable at 80
#: columns (typer's ``rich_help_panel``).
PANEL_ROBOT = "Robot, tool point and load"
PANEL_NOISE = "Noise figures (per measured component of one test row)"
PANEL_OUTPUT = "Output"


#: ``--program`` in --help: a short metavar, the choices in words (as one word,
#: ``<auto|krl|urscript|rapid|fanuc-ls|none>`` folds mid-word at 80 columns)
PROGRAM_METAVAR = "<program>"
PROGRAM_CHOICES = ("auto (default: by robot), krl (KUKA), urscript (UR), rapid (ABB), "
                   "fanuc-ls (FANUC), none")


def print_json(obj) -> None:
    """One JSON document on stdout (results.json key style: snake_case with SI units)."""
    import typer

    typer.echo(json.dumps(json_ready(obj), indent=2))


def output_dir(out: Path, force: bool, where: str = "--out") -> Path:
    """Check that ``out`` may be written: refuse a symbolic link, a file, and a non-empty
    directory unless ``force``. Nothing is created here (see :func:`writing_into`).

    ``campaign acquire`` and ``demo`` never overwrite a run; the other commands
    that write a directory follow the same rule, with ``--force`` to replace
    the files they write (other files are left alone; a file of theirs that is a
    symbolic link is refused, never written through).
    """
    from analysis.output_files import check_output_dir

    return check_output_dir(out, force, where)


def writing_into(out: Path):
    """Context manager: create ``out``; if the command then fails, remove what it created."""
    from analysis.output_files import created_dir

    return created_dir(out)


def text_width(stream=None) -> int | None:
    """Columns at which text for a person is wrapped on ``stream`` (default stdout).

    A terminal's own width; else ``$COLUMNS`` when set; else None: pipes and
    files keep whole lines (one message, one line, for logs and scripts).
    """
    import os
    import shutil
    import sys

    stream = sys.stdout if stream is None else stream
    try:
        if stream.isatty():
            return shutil.get_terminal_size().columns
    except (AttributeError, ValueError, OSError):
        pass
    columns = os.environ.get("COLUMNS", "")
    return int(columns) if columns.isdigit() and int(columns) > 0 else None


def echo(text: str = "", err: bool = False, nl: bool = True) -> None:
    """``typer.echo`` of text for a person, wrapped at word boundaries to :func:`text_width`."""
    import sys

    import typer

    typer.echo(wrap_text(text, text_width(sys.stderr if err else sys.stdout)), err=err, nl=nl)


@contextmanager
def stage(text: str, enabled: bool = True) -> Iterator[None]:
    """A spinner with the elapsed time on stderr while ``text`` runs (terminal only).

    Nothing is drawn when stderr is not a terminal (pipes, tests, --json), so
    machine-read output stays clean.
    """
    from rich.console import Console

    console = Console(stderr=True)
    if not (enabled and console.is_terminal):
        yield
        return
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    t0 = time.monotonic()
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                  console=console, transient=True) as progress:
        progress.add_task(text, total=None)
        yield
    console.print(f"{text}: {time.monotonic() - t0:.1f} s", style="dim")


@contextmanager
def progress_bar(text: str, total: int, enabled: bool = True):
    """A progress bar on stderr (terminal only); yields ``advance(n)``."""
    from rich.console import Console

    console = Console(stderr=True)
    if not (enabled and console.is_terminal):
        yield lambda n=1: None
        return
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("{task.description}"), BarColumn(),
                  TextColumn("{task.completed}/{task.total}"), TimeRemainingColumn(),
                  console=console, transient=True) as progress:
        task = progress.add_task(text, total=total)
        yield lambda n=1: progress.advance(task, n)
