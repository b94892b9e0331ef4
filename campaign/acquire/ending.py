"""What the operator reads when a session ends: the whole run's counts, what happened to
the robot and the load (read back from the session's records in ``events.jsonl``), and
the command that resumes the run.

Read from the files, not from the session's memory: the operator is told what the run
directory says, so a step that could not be recorded is not reported as done.
"""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from typing import Any

#: events that end a session early (written by the runner before it makes safe)
STOP_EVENTS = ("interrupt", "abort")


def run_counts(run_path: Path) -> dict[str, int]:
    """Finished measurements of the whole run (every session): ``done``, ``ok``, ``failed``."""
    from campaign.acquire.rundir import read_tests

    try:
        tests = read_tests(run_path)
    except (OSError, ValueError):
        return {}
    status = tests["status"].astype(str) if "status" in tests else []
    ok = int((status == "ok").sum()) if len(tests) else 0
    return {"done": int(len(tests)), "ok": ok, "failed": int(len(tests)) - ok}


def _session_events(run_path: Path, session: int | None) -> list[dict[str, Any]]:
    path = Path(run_path) / "events.jsonl"
    out = []
    try:
        lines = path.read_bytes().splitlines()
    except OSError:
        return out
    for line in lines:
        try:
            record = json.loads(line)
        except ValueError:
            continue
        if isinstance(record, dict) and (session is None or record.get("session") == session):
            out.append(record)
    return out


def safe_state(run_path: Path, session: int | None) -> str | None:
    """What the session's records say of the robot and the load after its stop, or None.

    None when the session did not stop early (no ``interrupt`` or ``abort``
    record). Otherwise one sentence: robot stopped (or not, or not recorded),
    load removed, still applied, or not on the tool at the stop.
    """
    events = _session_events(run_path, session)
    stops = [i for i, e in enumerate(events) if e.get("event") in STOP_EVENTS]
    if not stops:
        return None
    before, after = events[: stops[-1]], events[stops[-1] + 1:]
    robot = "robot stop not recorded in events.jsonl: check the robot"
    load = None
    for e in after:
        kind, why = e.get("event"), str(e.get("reason") or "")
        if kind == "robot_stopped":
            robot = "robot stopped"
        elif kind == "fault" and why.startswith("could not stop the robot"):
            robot = f"ROBOT NOT STOPPED ({why}): use the controller's stop"
        elif kind == "load_removed":
            load = "load removed"
        elif kind == "load_left":
            load = f"LOAD STILL APPLIED ({why})"
    if load is None:
        applied = False
        for e in before:
            if e.get("event") == "load_applied":
                applied = True
            elif e.get("event") == "load_removed":
                applied = False
        load = ("load removal not recorded in events.jsonl: check the tool" if applied
                else "no load was on the tool")
    return f"{robot}; {load}"


def resume_command(run_path: Path, fake: bool) -> str:
    """The command that continues ``run_path`` (``--fake`` when it was simulated)."""
    return "campaign acquire --resume " + shlex.quote(str(run_path)) + (" --fake" if fake
                                                                           else "")


def ending(run_path: Path, session: int | None, status: str, fake: bool,
           total: int | None) -> dict[str, Any]:
    """The summary of :meth:`Reporter.finish`: whole-run counts, ``total`` planned, the
    safe state after an early stop and, unless complete, the resume command."""
    out: dict[str, Any] = {"run_dir": str(run_path), **run_counts(run_path)}
    if total is not None:
        out["total"] = int(total)
    state = safe_state(run_path, session)
    if state is not None:
        out["safe_state"] = state
    if status not in ("complete", "dry-run"):
        out["resume"] = resume_command(run_path, fake)
    return out


def final_lines(status: str, reason: str, summary: dict[str, Any],
                elapsed_s: float | None = None) -> list[str]:
    """The last lines of a session, for a person: status and counts of the whole run, the
    robot and the load after an early stop, and how to resume."""
    done, total = summary.get("done"), summary.get("total")
    counts = (f"{done}/{total} measurements" if done is not None and total is not None
              else f"{summary.get('ok', 0) + summary.get('failed', 0)} measurements")
    counts += f": {summary.get('ok', 0)} ok, {summary.get('failed', 0)} failed"
    if elapsed_s is not None:
        counts += f"; this session {elapsed_s:.1f} s"
    lines = [f"run {status}{': ' + reason if reason else ''} ({counts}) -> "
             f"{summary.get('run_dir', '')}"]
    if summary.get("safe_state"):
        lines.append(f"after the stop: {summary['safe_state']}")
    if summary.get("resume"):
        lines.append(f"to continue: {summary['resume']}")
    return lines
