"""The ``place`` job: the workpiece placement and tool angles that minimise P's deflection.

The search itself lives in :mod:`campaign.use.place_run` (problem, Dask or local run,
outputs); this job checks the output directory, runs it, and removes a
directory it created when the search is refused. Its options record,
:class:`PlaceOptions`, is in the command line's units (mm, deg; ranges as ``A..B``
texts): one parser (:func:`campaign.use.place_run.build_problem`) reads them for both
faces, and the command line takes its defaults from the record (nothing to keep in
step). This module imports no numerical library: the command line reads it to build.
"""

from __future__ import annotations

import io
from dataclasses import MISSING, dataclass, fields, replace
from pathlib import Path
from types import MappingProxyType

__all__ = ["PlaceOptions", "PlaceResult", "run"]


@dataclass
class PlaceOptions:
    """The options of ``campaign place``, as the command line takes them (mm, deg; ranges
    as ``A..B`` texts, lists as comma-separated texts); the command's defaults are these
    (:data:`DEFAULTS`)."""

    robot: str
    path: Path
    out: Path
    x_mm: str
    y_mm: str
    z_mm: str
    tip: str | None = None
    tool_xyz_mm: str | None = None
    tool_rpy_deg: str | None = None
    yaw_deg: str = "0"
    x_step_mm: float = 100.0
    y_step_mm: float = 100.0
    z_step_mm: float = 100.0
    yaw_step_deg: float = 15.0
    tool_angle_deg: str = "-180..180"
    tool_angle_step_deg: float = 10.0
    max_joint_step_deg: float = 10.0
    config: str = "any"
    limit_margin_deg: float = 2.0
    min_inv_kappa: float = 0.05
    length: float | None = None
    keep_out_mm: str | None = None
    objective: str = "max"
    upper_bound: bool = False
    wrench: str | None = None
    joint_stiffness: str | None = None
    scheduler: str | None = None
    workers: int | None = None
    chunk: int | None = None
    runner_ups: int = 5
    program: str = "auto"
    max_evaluations: float | None = None
    max_memory_gib: float = 2.0
    force: bool = False  # write into a non-empty out (its files are replaced)


#: each option's default, by field name (the command line's defaults)
DEFAULTS = MappingProxyType({f.name: f.default for f in fields(PlaceOptions)
                             if f.default is not MISSING})


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
