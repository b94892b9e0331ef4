"""The ``place`` job: the workpiece placement and tool angles that minimise P's deflection.

The search itself lives in :mod:`campaign.use.place_run` (problem, Dask or local run,
outputs); this job checks the output directory, runs it, and removes a
directory it created when the search is refused. Its options record is
:class:`campaign.use.place_run.PlaceOptions`, in the command line's units (mm, deg;
ranges as ``A..B`` texts) because its ranges are texts that one parser reads
for both faces.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, replace
from pathlib import Path

from campaign.use.place_run import PlaceOptions

__all__ = ["PlaceOptions", "PlaceResult", "run"]


@dataclass
class PlaceResult:
    """placement: OUT/placement.json's document (mm, deg as its keys say); out: OUT."""

    placement: dict
    out: Path

    def to_json(self) -> dict:
        return self.placement


def run(o: PlaceOptions, console=None, progress=None,
        server_limit: float | None = None) -> PlaceResult:
    """Search and write OUT; ``console`` (a rich Console) gets the progress and summary
    lines (None: they are discarded); ``progress(fraction, text)`` the search's progress
    (an exception it raises stops the job, and OUT, if it made it, is removed);
    ``server_limit``: the evaluations a server allows per request (refused above)."""
    from rich.console import Console

    from analysis.output_files import check_output_dir, created_dir

    o = replace(o, path=Path(o.path), out=Path(o.out), objective=str(o.objective),
                program=str(o.program))
    from campaign.use.place_run import run_place

    check_output_dir(o.out, o.force)
    if console is None:
        console = Console(file=io.StringIO())
    with created_dir(o.out):  # a refused search leaves no OUT directory behind
        return PlaceResult(run_place(o, console, progress, server_limit), o.out)
