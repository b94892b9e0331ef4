"""``/api/acquire/map``, ``/poses``, ``/trace``: the Acquire view's zone map and live test.

Read from the files only (a reload, another tab or a restarted server shows the same):

- ``GET /map?run=RUN`` (or ``?plan=PLAN``): the plan's zone map, as the planner draws it
  (:mod:`campaign.planning.map_data`): zones, candidates passing the thresholds and the
  chosen poses with their joint angles (deg) and test ids. A run's own copies of the
  protocol and ``plan.csv`` give the poses; the candidates are drawn again with the seed
  and count of the plan directory's ``summary.json`` (``metadata.json`` ``plan_source``,
  when inside the workspace and its ``plan.csv`` is still the run's).
- ``GET /poses?run=RUN``: per pose of the plan, how many of its (test, repeat) rows are in
  ``tests.csv`` and its status: ``done`` (all rows, all ``ok``), ``failed`` (all rows,
  one ``failed``), ``partial`` (some rows) or ``pending``.
- ``GET /trace?run=RUN``: the test being measured, from the tail of the GUI job's events
  file: the displacement of P under the load as each tracker reading came in while it
  settled (mm, base frame), the wrench as read (N, N m, base frame) and, once the
  unloaded pose is read again, the test's displacement screw (mm, mrad).
"""

from __future__ import annotations

import contextlib
import csv
import json
from pathlib import Path

from fastapi import APIRouter, Depends, HTTPException, Query

from campaign.web.api_jobs import call, inside, workspace

router = APIRouter(prefix="/api/acquire", tags=["acquire-map"])
#: bytes read from the end of the events file at first for the test in progress
TAIL = 1 << 16
#: the line that opens a test (or its retry) in the events file
OPENS = b'"phase": "approach"'
#: most candidates drawn again for a map (the GUI's planner draws at most 100,000)
MAX_DRAWN = 200_000


class _Map:
    """The map's JSON for :func:`campaign.web.api_jobs.call` (InputError -> 400)."""

    def __init__(self, value: dict) -> None:
        self.value = value

    def to_json(self) -> dict:
        return self.value


def _latest(ws: Path) -> str:
    from campaign.web.acquire_api import JOBS

    try:
        return (ws / JOBS / "latest").read_text().strip()
    except OSError:
        raise HTTPException(404, "no acquisition started from this workspace") from None


def _run_dir(ws: Path, run: str | None) -> Path:
    run_dir = inside(ws, run if run is not None else _latest(ws), "run")
    if not (run_dir / "plan.csv").is_file():
        raise HTTPException(404, f"run: {run_dir.relative_to(ws)} has no plan.csv (not a run "
                                 "directory, or not created yet)")
    return run_dir


def _summary_of(ws: Path, run_dir: Path | None, plan_dir: Path) -> tuple[dict, str]:
    """(summary.json of the plan the run was made from, why not) -- {} when unknown."""
    from campaign.acquire.rundir import sha256_file

    source = plan_dir
    if run_dir is not None:
        try:
            meta = json.loads((run_dir / "metadata.json").read_text())
            source = Path(meta["plan_source"])
            source = source if source.is_absolute() else ws / source
        except (OSError, ValueError, KeyError, TypeError):
            return {}, "the run's metadata.json names no plan_source"
        try:
            if not source.resolve().is_relative_to(ws.resolve()):
                return {}, "the run's plan directory is outside the workspace"
            if sha256_file(source / "plan.csv") != meta.get("plan_sha256"):
                return {}, "the run's plan directory was planned again since"
        except OSError:
            return {}, "the run's plan directory is gone"
    try:
        return json.loads((source / "summary.json").read_text()), ""
    except (OSError, ValueError):
        return {}, "the plan directory has no summary.json"


def _map(ws: Path, run_dir: Path | None, plan_dir: Path) -> _Map:
    from campaign.planning.map_data import plan_map_data
    from campaign.planning.plan_output import read_plan

    protocol, plan = read_plan(run_dir or plan_dir)
    summary, why = _summary_of(ws, run_dir, plan_dir)
    try:
        seed, drawn = int(summary["seed"]), int(summary["candidates"]["drawn"])
    except (KeyError, TypeError, ValueError):
        seed = drawn = None
    if drawn is not None and not 0 < drawn <= MAX_DRAWN:
        seed, drawn, why = None, None, f"summary.json draws {drawn} (over {MAX_DRAWN})"
    data = plan_map_data(protocol, plan, seed, drawn)
    out = data.to_json()
    if why and seed is None:
        out["note"] = f"candidates not shown: {why}"
    out["robot"] = summary.get("robot") or protocol.campaign.robot
    out["poses_passing"] = summary.get("candidates", {}).get("poses_passing")
    return _Map(out)


@router.get("/map")
def zone_map(run: str | None = Query(None, max_length=1000),
             plan: str | None = Query(None, max_length=1000), ws: Path = Depends(workspace)):
    """The zone map of a run's plan (``run``) or of a plan directory (``plan``): theta_2 /
    theta_3 (deg, model convention), zones, candidates, chosen poses."""
    if run is not None and plan is not None:
        raise HTTPException(400, "give run or plan, not both")
    if plan is not None:
        plan_dir = inside(ws, plan, "plan")
        if not (plan_dir / "plan.csv").is_file():
            raise HTTPException(404, f"plan: {plan} has no plan.csv")
        return call(ws, lambda: _map(ws, None, plan_dir))
    run_dir = _run_dir(ws, run)
    return call(ws, lambda: _map(ws, run_dir, run_dir))


def test_rows(run_dir: Path) -> list[dict]:
    """tests.csv's rows as read now (a half-written last line is left out)."""
    try:
        text = (run_dir / "tests.csv").read_text(encoding="utf-8")
    except OSError:
        return []
    if not text.endswith("\n"):
        text = text[:text.rfind("\n") + 1]
    return list(csv.DictReader(text.splitlines()))


def pose_progress(plan_rows: list[dict], rows: list[dict]) -> list[dict]:
    """Per pose of the plan (``pose``, ``test``, ``repeats`` per row): its rows measured.

    ``rows``: tests.csv records (``test_id``, ``repeat``, ``status``). A pose is
    ``done`` when each (test, repeat) the plan asks of it has a row and all are ``ok``.
    """
    from campaign.planning.plan_output import MAX_REPEATS

    got: dict[tuple[int, int], str] = {}
    for r in rows:
        with contextlib.suppress(TypeError, ValueError):
            got[(int(float(r["test_id"])), int(float(r["repeat"])))] = r.get("status", "")
    poses: dict[str, dict] = {}
    for p in plan_rows:
        e = poses.setdefault(str(p["pose"]), {"pose": str(p["pose"]), "tests": [],
                                               "rows_planned": 0, "rows_done": 0,
                                               "rows_failed": 0})
        test, repeats = int(p["test"]), int(p["repeats"])
        if not 1 <= repeats <= MAX_REPEATS:
            raise ValueError(f"test {test}: repeats {repeats} outside 1..{MAX_REPEATS}")
        e["tests"].append(test)
        for rep in range(1, repeats + 1):
            e["rows_planned"] += 1
            status = got.get((test, rep))
            if status is not None:
                e["rows_done"] += 1
                e["rows_failed"] += status != "ok"
    for e in poses.values():
        if e["rows_done"] == 0:
            e["status"] = "pending"
        elif e["rows_done"] < e["rows_planned"]:
            e["status"] = "partial"
        else:
            e["status"] = "failed" if e["rows_failed"] else "done"
    return list(poses.values())


@router.get("/poses")
def poses(run: str | None = Query(None, max_length=1000), ws: Path = Depends(workspace)
          ) -> dict:
    """Per pose of the run's plan: rows measured (tests.csv) and its status."""
    run_dir = _run_dir(ws, run)
    try:
        with open(run_dir / "plan.csv", newline="", encoding="utf-8") as f:
            plan_rows = list(csv.DictReader(f))
        rows = test_rows(run_dir)
        out = pose_progress(plan_rows, rows)
    except (OSError, KeyError, TypeError, ValueError, UnicodeDecodeError) as err:
        raise HTTPException(400, f"{run_dir.relative_to(ws)}/plan.csv: not a plan table "
                                 f"({err})") from None
    return {"run_dir": str(run_dir.relative_to(ws)), "rows_read": len(rows), "poses": out,
            "done": [p["pose"] for p in out if p["status"] == "done"]}


def _tail_lines(path: Path) -> list[dict]:
    """The events file's lines from the last opening of a test (or all, if none)."""
    try:
        with open(path, "rb") as f:
            f.seek(0, 2)
            size = f.tell()
            span = TAIL
            while True:
                start = max(0, size - span)
                f.seek(start)
                chunk = f.read(size - start)
                at = chunk.rfind(OPENS)
                if at >= 0 or start == 0:
                    break
                span *= 4
    except OSError:
        return []
    if at >= 0:
        chunk = chunk[chunk.rfind(b"\n", 0, at) + 1:]
    elif start:
        chunk = chunk[chunk.find(b"\n") + 1:]
    out = []
    for line in chunk.split(b"\n"):
        with contextlib.suppress(ValueError):
            record = json.loads(line)
            if isinstance(record, dict):
                out.append(record)
    return out


def current_trace(lines: list[dict]) -> dict:
    """The test opened last in ``lines`` (events of the acquire job, in order).

    ``t_s``: wall-clock time since the load was applied (s); ``d_mm``: [dx, dy, dz]
    lists of the displacement readings while the load settled (mm, base frame);
    ``wrench``: the wrench as read under the load (N, N m, base frame; sensor mount
    nominal); ``result``: the test's displacement (mm) and rotation (mrad) once the
    pose is read unloaded again.
    """
    out: dict = {"test_id": None, "repeat": None, "attempt": None, "pose": None,
                 "phase": None, "t_s": [], "d_mm": [[], [], []], "wrench": None,
                 "result": None}
    t_load = None
    for r in lines:
        if r.get("event") != "phase":
            continue
        if r.get("phase") == "approach":
            out.update(test_id=r.get("test_id"), repeat=r.get("repeat"),
                       attempt=r.get("attempt"), pose=r.get("pose"), t_s=[],
                       d_mm=[[], [], []], wrench=None, result=None)
            t_load = None
        if "phase" in r:
            out["phase"] = r["phase"]
            if r["phase"] == "apply_load":
                t_load = r.get("elapsed_s")
        d, w = r.get("deflection_mm"), r.get("wrench")
        # the test's result: reported after its last reading (unloaded, or after the
        # load is removed when the reference readings were under a preload)
        if out["phase"] in ("unloaded_after", "settle_unloaded_after") and d is not None:
            out["result"] = {"d_mm": d, "r_mrad": r.get("rotation_mrad"), "wrench": w}
        elif d is not None and t_load is not None and "elapsed_s" in r:
            out["t_s"].append(round(r["elapsed_s"] - t_load, 4))
            for axis in range(3):
                out["d_mm"][axis].append(d[axis])
        if w is not None and out["result"] is None:
            out["wrench"] = w
    return out


@router.get("/trace")
def trace(run: str | None = Query(None, max_length=1000), ws: Path = Depends(workspace)
          ) -> dict:
    """The readings of the test in progress (or the last one) of the run's GUI job."""
    from campaign.web.acquire_api import _read

    run_dir = inside(ws, run if run is not None else _latest(ws), "run")
    record = _read(ws, run_dir)
    if not record:
        raise HTTPException(404, f"{run_dir.relative_to(ws)}: no acquisition started here")
    return {"run_dir": str(run_dir.relative_to(ws)),
            **current_trace(_tail_lines(ws / record["events_file"]))}
