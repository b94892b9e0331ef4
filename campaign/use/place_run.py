"""What ``campaign place`` does once its options are read: check them, build the
search, run it (in this process or on Dask), and write the outputs.

Outputs in ``--out``: ``placement.json``, ``path_joints.csv``, ``objective_xy.png``,
``path_deflection.png`` and, when the robot has a program format, the path as a
KRL (``place_path.src/.dat``), URScript (``place_path.script``), RAPID (``place_path.mod``) or
FANUC TP (``PLACE_PATH.LS``) program.
"""

from __future__ import annotations

import io
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from rich.console import Console

from analysis.errors import InputError
from analysis.kinetostatics.compensator_law import compensator_law_of
from analysis.kinetostatics.link_compliance import links_of
from analysis.model.ik import ALL_FLAGS
from analysis.output_files import make_dir, replacing, write_text

if TYPE_CHECKING:
    from campaign.jobs.place import PlaceOptions

OBJECTIVE_UNITS = {"max": "mm", "rms": "mm", "compliance": "mm/kN"}
#: what each objective is, for the colour bar of objective_xy.png
OBJECTIVE_TEXT = {"max": "largest |δp| along the path", "rms": "RMS |δp| along the path",
                  "compliance": "largest translational compliance along the path"}
#: Factor from SI (m, m/N) to the reported unit (mm, mm/kN).
OBJECTIVE_SCALE = {"max": 1e3, "rms": 1e3, "compliance": 1e6}
REASON_NAMES = {
    1: "unreachable (no inverse kinematics in this configuration)",
    2: "joint limits (with the margin)",
    3: "too close to a singularity (1/kappa_F below the threshold)",
    4: "a joint origin inside the keep-out box",
    5: "no continuous path (every point is reachable, but not within the joint step bound)",
}
#: Infeasible placements listed one by one in placement.json (all are counted).
MAX_LISTED = 2000
#: Evaluations (placement x point x tool angle x configuration) a search may have without
#: --max-evaluations or --scheduler: a few minutes on one core at the 0.3-1e6 evaluations/s
#: a whole search step runs at (docs/place.md, Speed); more is refused before any work.
DEFAULT_MAX_EVALUATIONS = 100_000_000
#: Values one grid axis may have (a 1 um step over a metre): refused before the axis
#: is made.
MAX_AXIS_VALUES = 1_000_000


def parse_range(text: str, where: str) -> tuple[float, float]:
    """``A..B`` or ``A`` -> (A, B) with A <= B."""
    from campaign.options import parse_floats

    parts = text.split("..")
    if len(parts) > 2 or not all(p.strip() for p in parts):
        raise InputError(f"expected A..B or A, got {text!r}", where=where)
    vals = [float(parse_floats(p, where, 1)[0]) for p in parts]
    lo, hi = vals[0], vals[-1]
    if lo > hi:
        raise InputError(f"expected A <= B in A..B, got {text!r}", where=where)
    return lo, hi


def grid(text: str, step: float, where: str, turn: float | None = None) -> np.ndarray:
    """Grid values of a range with ``step``; a full ``turn`` leaves out its duplicate end."""
    lo, hi = parse_range(text, where)
    if lo == hi:
        return np.array([lo])
    if not (step > 0 and np.isfinite(step)):
        raise InputError("expected a positive step", where=f"{where} step")
    count = np.floor((hi - lo) / step + 1e-9) + 1
    if count > MAX_AXIS_VALUES:
        raise InputError(f"{count:.3g} grid values from {lo:g} to {hi:g} in steps of "
                         f"{step:g}: more than {MAX_AXIS_VALUES:.0e}; use a coarser step",
                         where=f"{where} step")
    values = np.arange(lo, hi + step * 1e-9, step)
    if turn is not None and hi - lo >= turn - 1e-9:
        values = values[values < lo + turn - 1e-9]
    return values


def parse_flags(text: str) -> tuple[tuple[int, int, int], ...]:
    """``any`` -> all eight configurations; ``s,e,w`` (each +1 or -1) -> that one."""
    if text.strip().lower() == "any":
        return ALL_FLAGS
    try:
        flags = tuple(int(s) for s in text.split(","))
    except ValueError:
        flags = ()
    if len(flags) != 3 or any(f not in (1, -1) for f in flags):
        raise InputError("expected 'any' or shoulder,elbow,wrist each +1 or -1 (e.g. -1,1,1)",
                         where="--config")
    return (flags,)  # type: ignore[return-value]


def parse_keep_out(text: str | None) -> np.ndarray | None:
    """``x0..x1,y0..y1,z0..z1`` (mm) -> (3, 2) box (m)."""
    if not text:
        return None
    parts = text.split(",")
    if len(parts) != 3:
        raise InputError("expected x0..x1,y0..y1,z0..z1 in mm", where="--keep-out-mm")
    return 1e-3 * np.array([parse_range(p, "--keep-out-mm") for p in parts])


def build_problem(o: PlaceOptions, console: Console):
    """(robot, Problem, placements (P, 4) SI, grids (mm/deg), assumptions) from the options."""
    from analysis.kinetostatics.dexterity import characteristic_length
    from analysis.model.ik import IKSolver
    from analysis.placement.evaluate import Problem
    from analysis.placement.grid import PlacementGrid
    from analysis.placement.path import read_part_path
    from analysis.report.formatting import k_kNm
    from campaign.options import parse_floats, robot_option, stiffness_option

    if o.objective not in OBJECTIVE_UNITS:
        raise InputError("expected max, rms or compliance", where="--objective")
    if o.program not in ("auto", "krl", "urscript", "rapid", "fanuc-ls", "none"):
        raise InputError("expected auto, krl, urscript, rapid, fanuc-ls or none",
                         where="--program")
    if not (np.isfinite(o.max_joint_step_deg) and o.max_joint_step_deg > 0):
        raise InputError("expected a positive number", where="--max-joint-step-deg")
    if not 0 <= o.min_inv_kappa < 1:  # NaN fails too
        raise InputError(f"expected 0 <= 1/kappa_F < 1 (0: no singularity check), got "
                         f"{o.min_inv_kappa:g}", where="--min-inv-kappa")
    if not 0 <= o.limit_margin_deg < 90:
        raise InputError("expected 0 <= margin < 90 deg", where="--limit-margin-deg")
    if o.workers is not None and o.workers < 0:
        raise InputError("expected 0 or more workers", where="--workers")
    if o.chunk is not None and o.chunk < 1:
        raise InputError("expected at least one placement per task", where="--chunk")
    if o.max_evaluations is not None and not (o.max_evaluations >= 1
                                              and np.isfinite(o.max_evaluations)):
        raise InputError("expected a positive number of evaluations", where="--max-evaluations")
    if not (o.max_memory_gib > 0 and np.isfinite(o.max_memory_gib)):
        raise InputError("expected a positive size in GiB", where="--max-memory-gib")
    from campaign.jobs.option_checks import six_joints

    robot = robot_option(o.robot, o.tip, o.tool_xyz_mm, o.tool_rpy_deg)
    six_joints(robot)
    k = stiffness_option(robot, o.joint_stiffness)
    part = read_part_path(o.path)
    assumptions = []
    if o.wrench is not None:
        wrench = np.tile(parse_floats(o.wrench, "--wrench", 6), (part.n, 1))
        assumptions.append("process wrench: --wrench, constant, tool frame at P")
    elif part.wrench is not None:
        wrench = part.wrench
        assumptions.append(f"process wrench: per row of {part.source}, tool frame at P")
    elif o.objective == "compliance":
        wrench = None
    else:
        raise InputError("no process wrench: add fx_N..mz_Nm columns to the path file or give "
                         "--wrench fx,fy,fz,mx,my,mz (tool frame), or use --objective "
                         "compliance", where="--wrench")
    if wrench is not None and not np.any(wrench) and o.objective != "compliance":
        src = "--wrench" if o.wrench is not None else f"{part.source} (wrench columns)"
        raise InputError("the process wrench is zero on every path point: every placement "
                         "deflects 0 and there is nothing to minimise; give the process "
                         "wrench, or use --objective compliance", where=src)
    cov = getattr(robot, "compliance_covariance", None)
    if o.upper_bound and cov is None:
        raise InputError(f"{robot.name} has no stiffness covariance (no [identification] "
                         "table of an identified model.toml): the 95 % upper bound is "
                         "unavailable", where="--upper-bound")
    if o.upper_bound and o.objective == "compliance":
        raise InputError("the upper bound applies to the deflection objectives max and rms",
                         where="--upper-bound")
    length, how = o.length, "given on the command line"
    if length is not None and not (np.isfinite(length) and length > 0):
        raise InputError("expected a positive length in m", where="--length")
    if length is None and robot.characteristic_length is not None:
        length, how = robot.characteristic_length, "from the robot model"
    elif length is None:
        length, _, _ = characteristic_length(robot)
        how = "computed (minimum condition number of J_N)"
    xs = grid(o.x_mm, o.x_step_mm, "--x-mm")
    ys = grid(o.y_mm, o.y_step_mm, "--y-mm")
    zs = grid(o.z_mm, o.z_step_mm, "--z-mm")
    yaws = grid(o.yaw_deg, o.yaw_step_deg, "--yaw-deg", turn=360.0)
    angles = grid(o.tool_angle_deg, o.tool_angle_step_deg, "--tool-angle-deg", turn=360.0)
    solver = IKSolver.for_robot(robot)
    flags = parse_flags(o.config) if solver.kind != "numerical" else solver.flags
    if solver.kind == "numerical" and o.config.strip().lower() != "any":
        raise InputError("this robot's chain has no closed-form IK, so no configuration "
                         "flags: leave --config at 'any'", where="--config")
    problem = Problem(
        robot=robot, points=part.points, axes=part.axes, wrench=wrench,
        angles=np.radians(angles), k=np.asarray(k, dtype=float), length=float(length),
        min_inv_kappa=o.min_inv_kappa, margin=np.radians(o.limit_margin_deg),
        max_step=np.radians(o.max_joint_step_deg), objective=o.objective, flags=flags,
        keep_out=parse_keep_out(o.keep_out_mm), cov_x=cov if o.upper_bound else None,
    )
    G = PlacementGrid(1e-3 * xs, 1e-3 * ys, 1e-3 * zs, np.radians(yaws))
    assumptions += [
        f"robot {robot.name}: inverse kinematics {solver.kind}; P = the robot file's tool point",
        f"joint stiffness [{', '.join(k_kNm(v) for v in k)}] kN m/rad",
        "search model: linear compliance without K_C, dX = J K_theta^-1 J^T w; the best "
        "placement is re-checked with the nonlinear equilibrium with K_C",
        f"characteristic length L = {length:.4f} m ({how}); singular below 1/kappa_F = "
        f"{o.min_inv_kappa:g} (checked at the chosen angles)",
        f"joint-limit margin {o.limit_margin_deg:g} deg; joint step bound "
        f"{o.max_joint_step_deg:g} deg between neighbouring points",
        "tool frame: z = the path's tool axis; x at angle 0 = the workpiece x axis made "
        "perpendicular to z (y where the axis is within 25 deg of x)",
        "placement: p_base = (x, y, z) + Rz(yaw) p_part",
    ]
    if problem.keep_out is not None:
        assumptions.append("keep-out box: checked on the joint origins, not the link volumes")
    if links_of(robot):
        assumptions.append(
            "model class with link compliance (links " + ", ".join(
                str(lc.link) for lc in links_of(robot)) + " of the model file): the search "
            "model is the joint springs only; the re-check of the best placement adds the "
            "links' sum_l J_l C_l J_l^T w")
    if compensator_law_of(robot) is not None:
        assumptions.append(
            "model class with the axis-2 compensator law (the model file's k2(q2)): the "
            "search model takes k2 at the law's reference q2; the re-check of the best "
            "placement takes k2(q2) at each point")
    if cov is not None and not o.upper_bound:
        assumptions.append("the model has a stiffness covariance: --upper-bound would "
                           "minimise the 95 % upper bound instead of the mean")
    grids = {"x_mm": xs, "y_mm": ys, "z_mm": zs, "yaw_deg": yaws, "tool_angle_deg": angles}
    return robot, problem, G, grids, assumptions, part


@dataclass(frozen=True)
class SearchSize:
    """The size of a search, known before any work (exact integers).

    placements, points, angles, configurations; evaluations = their product;
    result_bytes: the per-placement results kept (17 + 4 points bytes each).
    """

    placements: int
    points: int
    angles: int
    configurations: int
    result_bytes: int

    @property
    def evaluations(self) -> int:
        return self.placements * self.points * self.angles * self.configurations

    def text(self) -> str:
        return (f"{self.placements} placements x {self.points} points x {self.angles} tool "
                f"angles x {self.configurations} configurations = {self.evaluations} "
                "evaluations")


def search_size(problem, G) -> SearchSize:
    """:class:`SearchSize` of ``problem`` over the placement grid ``G``."""
    from analysis.placement.search import result_bytes

    P, N = len(G), int(problem.points.shape[0])
    return SearchSize(P, N, int(problem.angles.size), len(problem.flags), result_bytes(P, N))


def check_size(size: SearchSize, o: PlaceOptions, server_limit: float | None = None) -> None:
    """Refuse a search above the evaluation or memory limit (before any work).

    The evaluation limit is --max-evaluations when given, else
    :data:`DEFAULT_MAX_EVALUATIONS` unless --scheduler sends the work to a cluster.
    The memory limit (--max-memory-gib) bounds the results kept in this process.
    ``server_limit``: the evaluations a web server allows per request, above any of those.
    """
    where = "--x-mm/--y-mm/--z-mm/--yaw-deg/--tool-angle-deg and their steps"
    if server_limit is not None and size.evaluations > server_limit:
        raise InputError(f"the search has {size.text()} ({size.evaluations:.3g}), above this "
                         f"server's limit of {server_limit:.3g} evaluations per request: "
                         "coarsen the steps or narrow the box", where=where)
    limit = o.max_evaluations
    if limit is None and not o.scheduler:
        limit = DEFAULT_MAX_EVALUATIONS
    if limit is not None and size.evaluations > limit:
        how = ("raise --max-evaluations" if o.max_evaluations is not None else
               "allow it with --max-evaluations N or run it on a cluster with --scheduler")
        raise InputError(f"the search has {size.text()} ({size.evaluations:.3g}), above the "
                         f"limit of {limit:.3g}: coarsen the steps or narrow the box, or {how}",
                         where=where)
    gib = size.result_bytes / 2**30
    if gib > o.max_memory_gib:
        raise InputError(f"the search's {size.placements} placements need {gib:.3g} GiB for "
                         f"their results ({size.result_bytes // size.placements} bytes each), "
                         f"above --max-memory-gib {o.max_memory_gib:g}: coarsen the steps or "
                         "narrow the box", where=where)


def estimate_line(probe, size: SearchSize, workers: int, expected: float,
                  share: float, how_share: str) -> str:
    """Time and memory of the search from a timed probe (:mod:`analysis.placement.probe`),
    as one line: ``expected`` (s, :func:`analysis.placement.probe.expected_seconds`)
    with the core ``share`` it assumed and whence (``how_share``); memory = the
    results plus one probe's peak per worker."""
    n = probe.placements
    evaluations = n * size.angles * size.points * size.configurations
    rate = evaluations / max(probe.seconds, 1e-9)
    cpu_rate = evaluations / max(probe.cpu_seconds or probe.seconds, 1e-9)
    memory = size.result_bytes + workers * probe.peak_bytes
    return (f"expected {_duration(expected)} on {workers} "
            f"process{'es' if workers > 1 else ''} and {memory / 2**20:.3g} MiB "
            f"(timed probe of {n} placement{'s' if n > 1 else ''} spread over the box, "
            f"where the search runs: {rate:.3g} evaluations/s per process, "
            f"{cpu_rate:.3g} per CPU second; {share:.0%} of a core per process "
            f"{how_share}; peak {probe.peak_bytes / 2**20:.3g} MiB; results "
            f"{size.result_bytes / 2**20:.3g} MiB)")


def _duration(seconds: float) -> str:
    if seconds < 120:
        return f"{seconds:.2g} s"
    if seconds < 7200:
        return f"{seconds / 60:.3g} min"
    return f"{seconds / 3600:.3g} h"


def _search(problem, G, size: SearchSize, o: PlaceOptions, console: Console, progress=None):
    """Probe, then search every placement; returns (ChunkResult, run facts for
    placement.json). ``progress(done, total)`` after each task (a chunk of placements)."""
    from analysis.placement.probe import (
        batch_placements,
        core_share,
        expected_seconds,
        probe_sample,
        task_chunk,
    )
    from campaign.text_wrap import print_wrapped
    from campaign.use.place_cluster import other_runnable, search_runner

    # the machine's load before this command's workers exist: the other processes the
    # local workers will share the cores with
    load, how_load = other_runnable()
    load_average = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    with search_runner(o.scheduler, o.workers) as runner:
        if runner.client is not None:
            print_wrapped(console, f"{runner.how}: ready in {runner.startup_seconds:.2g} s")
        batch = batch_placements(size.points, size.angles)
        probed = runner.probe(problem, probe_sample(G, batch))
        chunk = o.chunk or task_chunk(probed, len(G), runner.workers, batch)
        if o.scheduler:
            # another machine's load is not known here: the share the probe itself got
            share = min(1.0, (probed.cpu_seconds or probed.seconds) / max(probed.seconds,
                                                                           1e-9))
            how_share = "as the probe had it"
        else:
            share = core_share(load, runner.workers, os.cpu_count() or 1)
            how_share = f"{how_load} on {os.cpu_count() or 1} cores"
        expected = expected_seconds(probed, size.placements, runner.workers, chunk, share)
        print_wrapped(console, estimate_line(probed, size, runner.workers, expected, share,
                                             how_share))
        console.print(f"searching {runner.how}; {len(G)} placements in tasks of {chunk}"
                      if runner.client is None else
                      f"searching on the {runner.how}; {len(G)} placements in tasks of "
                      f"{chunk}")
        cpu0 = runner.cpu_seconds()
        t0 = time.perf_counter()
        if runner.client is None:
            with console.status("searching in this process"):
                res = runner.run(problem, G, chunk, progress)
        else:
            res = runner.run(problem, G, chunk, progress)
        elapsed = time.perf_counter() - t0
        cpu = runner.cpu_seconds() - cpu0
    facts = {"where": runner.how, "seconds": round(elapsed, 3),
             "evaluations_per_second": round(size.evaluations / max(elapsed, 1e-9)),
             # the evaluating processes' CPU over the search (all their threads): beside
             # the probe's per CPU second, the search's own cost whatever the machine's load
             "cpu_seconds": round(cpu, 3),
             "evaluations_per_cpu_second": round(size.evaluations / max(cpu, 1e-9)),
             "expected_seconds": round(expected, 3),
             # the probe's own wall time scaled to the search (the estimate before issue 36's
             # core share), for the benchmark's comparison
             "expected_seconds_probe_wall": round(
                 probed.seconds_per_placement * size.placements / runner.workers, 3),
             "probe_seconds": round(probed.seconds, 4),
             "probe_cpu_seconds": (None if probed.cpu_seconds is None
                                   else round(probed.cpu_seconds, 4)),
             "probe_placements": probed.placements,
             "other_runnable": round(load, 2),
             "load_average": None if load_average is None else round(load_average, 2),
             "core_share": round(share, 3),
             "startup_seconds": round(runner.startup_seconds, 3),
             "placements_per_task": int(chunk)}
    return res, facts


#: the search box's dimensions as (grid key, option, unit, full turn)
BOX_DIMENSIONS = (("x_mm", "--x-mm", "mm", None), ("y_mm", "--y-mm", "mm", None),
                  ("z_mm", "--z-mm", "mm", None), ("yaw_deg", "--yaw-deg", "deg", 360.0))


def edge_warnings(grids: dict, index: int) -> list[str]:
    """One sentence per dimension where placement ``index`` lies on the search box's edge.

    ``grids`` maps x_mm, y_mm, z_mm, yaw_deg to their grid values (mm, deg);
    ``index`` is a row of the placements, laid out x, y, z, yaw (C order). A
    best placement on an edge may have a better one just outside the box; a
    dimension with one value, or a yaw grid covering a full turn, has no edge.
    """
    shape = tuple(len(grids[key]) for key, *_ in BOX_DIMENSIONS)
    at = np.unravel_index(int(index), shape)
    notes = []
    for i, (key, option, unit, turn) in zip(at, BOX_DIMENSIONS, strict=True):
        values = np.asarray(grids[key], dtype=float)
        if values.size < 2 or i not in (0, values.size - 1):
            continue
        step = values[1] - values[0]
        if turn is not None and values[-1] - values[0] + step >= turn - 1e-9:
            continue
        end = "lower" if i == 0 else "upper"
        notes.append(f"the best placement is on the {end} edge of {option} "
                     f"({key.split('_')[0]} = {values[i]:g} {unit}, range {values[0]:g}.."
                     f"{values[-1]:g} {unit}): a better one may lie outside the box; widen "
                     f"{option}")
    return notes


def _placement_dict(p: np.ndarray) -> dict:
    return {"x_mm": round(1e3 * p[0], 6), "y_mm": round(1e3 * p[1], 6),
            "z_mm": round(1e3 * p[2], 6), "yaw_deg": round(float(np.degrees(p[3])), 9)}


def check_search(o: PlaceOptions, server_limit: float | None = None) -> SearchSize:
    """The size of the search the options ask for, or InputError (every check of the
    options and the size limits, no search): what a web server answers before queuing."""
    _, problem, G, *_ = build_problem(o, Console(file=io.StringIO()))
    size = search_size(problem, G)
    check_size(size, o, server_limit)
    return size


def run_place(o: PlaceOptions, console: Console | None = None, progress=None,
              server_limit: float | None = None) -> dict:
    """The whole search; returns placement.json's document; raises InputError on bad input
    or when nothing is feasible. ``console`` gets the progress and summary lines;
    ``progress(fraction, text)`` the search's progress (an exception it raises stops the
    search); ``server_limit``: see :func:`check_size`."""
    from analysis.placement.details import path_details
    from analysis.placement.search import evaluate_chunk
    from campaign.text_wrap import print_wrapped

    console = console or Console()
    robot, problem, G, grids, assumptions, part = build_problem(o, console)
    size = search_size(problem, G)
    check_size(size, o, server_limit)
    N, evaluations = size.points, size.evaluations
    print_wrapped(console, f"search: {size.text()}")
    tasks = None
    if progress is not None:
        progress(0.0, f"search: {size.text()}")

        def tasks(done: int, total: int) -> None:
            progress(done / total, f"searching: {done} of {total} tasks "
                     f"({len(G)} placements)")
    res, run_facts = _search(problem, G, size, o, console, tasks)
    elapsed, how = run_facts["seconds"], run_facts["where"]
    if progress is not None:
        progress(1.0, "search done; writing placement.json, path_joints.csv, plots")
    center = np.array([0.5 * (grids[k][0] + grids[k][-1]) for k in ("x_mm", "y_mm", "z_mm")]
                      + [0.5 * (grids["yaw_deg"][0] + grids["yaw_deg"][-1])])
    center = np.concatenate([1e-3 * center[:3], np.radians(center[3:])])
    cres = evaluate_chunk(problem, center[None])
    feasible = np.flatnonzero(np.isfinite(res.value))
    scale, unit = OBJECTIVE_SCALE[o.objective], OBJECTIVE_UNITS[o.objective]
    infeasible = np.flatnonzero(~np.isfinite(res.value))
    by_reason = {REASON_NAMES[c]: int(np.sum(res.reason[infeasible] == c))
                 for c in sorted(REASON_NAMES) if np.any(res.reason[infeasible] == c)}
    if feasible.size == 0:
        raise InputError(f"no feasible placement among {len(G)}: "
                         + "; ".join(f"{v} {k}" for k, v in by_reason.items())
                         + " (widen the box, relax --min-inv-kappa, --max-joint-step-deg or "
                         "--limit-margin-deg)", where="--x-mm/--y-mm/--z-mm")
    order = feasible[np.argsort(res.value[feasible], kind="stable")]
    best = order[0]
    flags = problem.flags[res.config[best]]
    details = path_details(problem, G[best], flags, res.angle[best])
    if not np.isclose(details.value, res.value[best], rtol=1e-9, atol=1e-15):
        raise InputError(f"internal check failed: the best placement's objective "
                         f"{details.value:.6g} differs from the search's "
                         f"{res.value[best]:.6g}", where="campaign place")
    center_details = None
    if np.isfinite(cres.value[0]):
        center_details = path_details(problem, center, problem.flags[cres.config[0]],
                                      cres.angle[0])
    make_dir(o.out)
    _write_path_csv(o.out / "path_joints.csv", robot, details, part, problem)
    summary = {
        "robot": robot.name,
        "path_file": str(o.path),
        "placement": _placement_dict(G[best]),
        "objective": float(scale * res.value[best]),
        "objective_name": o.objective + (" (95 % upper bound)" if o.upper_bound else ""),
        "objective_unit": unit,
        "objective_nonlinear": (None if details.value_nonlinear is None
                                else float(scale * details.value_nonlinear)),
        "configuration": {"shoulder": flags[0], "elbow": flags[1], "wrist": flags[2]},
        "center_placement": _placement_dict(center),
        "center_objective": float(scale * cres.value[0]) if np.isfinite(cres.value[0]) else None,
        "center_infeasible_reason": (None if np.isfinite(cres.value[0])
                                     else REASON_NAMES[int(cres.reason[0])]),
        "improvement_over_center": (float(cres.value[0] / res.value[best])
                                    if np.isfinite(cres.value[0]) and res.value[best] > 0
                                    else None),
        "runner_ups": [{"placement": _placement_dict(G[i]),
                        "objective": float(scale * res.value[i])}
                       for i in order[1:1 + max(0, o.runner_ups)]],
        "search_space": {
            "method": "exhaustive grid (see docs/place.md for why not an optimizer)",
            **{k: v.tolist() for k, v in grids.items()},
            "configurations": [list(f) for f in problem.flags],
            "placements": len(G), "points": int(N),
            "evaluations": int(evaluations),
        },
        "infeasible": {
            "count": int(infeasible.size), "by_reason": by_reason,
            "listed": int(min(infeasible.size, MAX_LISTED)),
            "placements": [{**_placement_dict(G[i]), "reason": REASON_NAMES[int(res.reason[i])],
                            "path_point": int(res.point[i]) + 1}
                           for i in infeasible[:MAX_LISTED]],
        },
        "run": run_facts,
        "assumptions": assumptions,
        "warnings": edge_warnings(grids, best),
    }
    # allow_nan=False: NaN or inf are not JSON; a non-finite number is a bug, not output
    write_text(o.out / "placement.json", json.dumps(summary, indent=2, allow_nan=False) + "\n")
    _plots(o, problem, G, res, grids, best, details, center_details, unit, scale, robot)
    programs = _programs(o, robot, details)
    for line in assumptions:
        print_wrapped(console, f"assumed: {line}")
    p = summary["placement"]
    nonlinear = summary["objective_nonlinear"]
    check = ("" if nonlinear is None else
             f" (nonlinear equilibrium with K_C: {nonlinear:.4g} {unit})")
    print_wrapped(console, f"best placement x = {p['x_mm']:g} mm, y = {p['y_mm']:g} mm, z = "
                  f"{p['z_mm']:g} mm, yaw = {p['yaw_deg']:g} deg; {o.objective} = "
                  f"{summary['objective']:.4g} {unit}{check}")
    for note in summary["warnings"]:
        print_wrapped(console, f"warning: {note}", style="yellow")
    if summary["improvement_over_center"] is not None:
        print_wrapped(console, f"centre of the box: {summary['center_objective']:.4g} {unit} "
                      f"(x {summary['improvement_over_center']:.3g} better at the best)")
    elif summary["center_objective"] is not None:
        print_wrapped(console, f"centre of the box: {summary['center_objective']:.4g} {unit}")
    else:
        print_wrapped(console, "centre of the box infeasible: "
                      f"{summary['center_infeasible_reason']}")
    print_wrapped(console, f"{infeasible.size} of {len(G)} placements infeasible"
                  + (": " + "; ".join(f"{v} {k}" for k, v in by_reason.items())
                     if by_reason else ""))
    print_wrapped(console, f"wrote placement.json, path_joints.csv, plots{programs} to {o.out}/ "
                  f"({elapsed:.2f} s, {how})")
    return summary


def _write_path_csv(path: Path, robot, d, part, problem) -> None:
    import csv

    with replacing(path) as tmp, tmp.open("w", newline="") as fh:
        wr = csv.writer(fh)
        head = ["point", "line", *(f"q{j + 1}_deg" for j in range(robot.n)), "tool_angle_deg",
                "x_mm", "y_mm", "z_mm", "dx_mm", "dy_mm", "dz_mm", "d_mm"]
        if d.dp_nonlinear is not None:
            head += ["dx_nonlinear_mm", "dy_nonlinear_mm", "dz_nonlinear_mm"]
        head += ["inv_kappa_F"]
        wr.writerow(head)
        for i in range(d.q.shape[0]):
            row = [i + 1, int(part.line[i]), *(f"{v:.12g}" for v in np.degrees(d.q[i])),
                   f"{np.degrees(d.angle[i]):.12g}",
                   *(f"{v:.12g}" for v in 1e3 * d.target[i, :3, 3]),
                   *(f"{v:.12g}" for v in 1e3 * d.dp[i]),
                   f"{1e3 * np.linalg.norm(d.dp[i]):.12g}"]
            if d.dp_nonlinear is not None:
                row += [f"{v:.12g}" for v in 1e3 * d.dp_nonlinear[i]]
            row += [f"{d.inv_kappa[i]:.6g}"]
            wr.writerow(row)


def _plots(o, problem, G, res, grids, best, details, center_details, unit, scale, robot):
    from analysis.placement.plots import plot_objective_map, plot_path_deflection

    shape = tuple(len(grids[k]) for k in ("x_mm", "y_mm", "z_mm", "yaw_deg"))
    values = (scale * res.value).reshape(shape)
    ib = np.unravel_index(best, shape)
    sl = np.where(np.isfinite(values[:, :, ib[2], ib[3]]), values[:, :, ib[2], ib[3]], np.nan)
    what = OBJECTIVE_TEXT.get(o.objective, o.objective)
    if problem.cov_x is not None and o.objective != "compliance":
        what = f"95 % upper bound of the {what}"
    plot_objective_map(grids["x_mm"], grids["y_mm"], sl,
                       (grids["x_mm"][ib[0]], grids["y_mm"][ib[1]]),
                       f"{robot.name}: {o.objective} at z = {grids['z_mm'][ib[2]]:g} mm, "
                       f"yaw = {grids['yaw_deg'][ib[3]]:g} deg", f"{what} ({unit})",
                       o.out / "objective_xy.png")
    if problem.wrench is not None:
        center = (None if center_details is None
                  else 1e3 * np.linalg.norm(center_details.dp, axis=1))
        # with the stiffness covariance the per-point cost is the 95 % upper bound of |dp|
        upper = (1e3 * details.cost if problem.cov_x is not None
                 and o.objective != "compliance" else None)
        plot_path_deflection(1e3 * np.linalg.norm(details.dp, axis=1), center,
                             f"{robot.name}: deflection of P along the path (search model)",
                             o.out / "path_deflection.png", upper)


def _programs(o, robot, details) -> str:
    """Write the path as a robot program; returns a note for the summary line."""
    from analysis.export.robot_programs import default_format, write_program

    kind = o.program
    if kind == "auto":
        kind = default_format(robot.name, robot.key) or "none"
    if kind == "none":
        return ""
    wrench = (f"--wrench {o.wrench} (N, N m, tool frame)" if o.wrench is not None
              else "the path file's wrench columns, if any (tool frame)")
    note = [f"campaign place: {robot.name}, path {o.path}, best placement",
            f"process wrench: {wrench}",
            "joint targets in the controller convention; the path is not compensated"]
    files = write_program(kind, o.out, "place_path", robot.to_controller(details.q), note)
    label = {"krl": "KRL", "urscript": "URScript", "rapid": "RAPID", "fanuc-ls": "FANUC TP"}
    return f", {'/'.join(f.name for f in files)} ({label[kind]})"
