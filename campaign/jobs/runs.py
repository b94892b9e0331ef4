"""The Runs view's job: every plan, run and analysis in a workspace (read-only).

A directory is a *plan* when it holds ``plan.csv`` and ``summary.json`` (what
``campaign plan`` writes), a *run* when it holds ``metadata.json`` (``campaign
acquire``), an *analysis* when it holds ``results.json`` (``campaign
analyze``). Symbolic links are not followed; hidden directories (a run being
created is ``.NAME.creating-...``) are skipped. A file that cannot be read is
listed with status ``unreadable`` and the reason, never skipped silently.
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

MAX_DEPTH = 5
MAX_ENTRIES = 1000
MAX_JSON_BYTES = 50_000_000  # results.json of a million-test import stays far below


@dataclass(frozen=True)
class Entry:
    """One item of the workspace. ``k`` (N m/rad) per joint: a plan's prior with its
    predicted standard error, an analysis' identified k with its 95 % interval."""

    kind: str  # plan, run, analysis
    path: str  # relative to the workspace, POSIX separators
    robot: str
    date_utc: str
    status: str
    detail: str = ""
    k: list[dict] = field(default_factory=list)
    files: list[str] = field(default_factory=list)  # what the page links to (relative paths)


def _load(path: Path) -> dict:
    if path.is_symlink() or path.stat().st_size > MAX_JSON_BYTES:
        raise ValueError("a symbolic link or a file too large to list")
    data = json.loads(path.read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise ValueError("not a JSON object")
    return data


def _mtime(path: Path) -> str:
    return datetime.fromtimestamp(path.stat().st_mtime, UTC).isoformat(timespec="seconds")


def _seconds(text: str) -> str:
    """An ISO time to the second (as the other entries' dates), else as written."""
    try:
        return datetime.fromisoformat(text).isoformat(timespec="seconds")
    except ValueError:
        return text


def _plan(d: Path, rel: str) -> Entry:
    s = _load(d / "summary.json")
    k = [{"joint": r["joint"], "k_Nm_per_rad": r["k_prior_N_m_per_rad"],
          "se_Nm_per_rad": r["se_design_N_m_per_rad"]}
         for r in s.get("predicted_standard_errors", [])]
    tests = s.get("tests")
    n = len(tests) if isinstance(tests, list) else tests
    return Entry("plan", rel, str(s.get("robot", "")), _mtime(d / "plan.csv"), "planned",
                 f"{n} tests, {s.get('strategy', '')}", k)


def _run(d: Path, rel: str) -> Entry:
    m = _load(d / "metadata.json")
    robot = m.get("robot", {})
    name = robot.get("name", "") if isinstance(robot, dict) else str(robot)
    rows = 0
    tests = d / "tests.csv"
    if tests.is_file() and not tests.is_symlink():
        with tests.open("rb") as fh:
            rows = max(0, sum(1 for _ in fh) - 1)
    detail = f"{rows} test rows measured, {m.get('n_planned_tests', '?')} tests planned"
    if m.get("reason"):
        detail += f"; {m['reason']}"
    return Entry("run", rel, name, _seconds(str(m.get("started_utc", "")))
                 or _mtime(d / "metadata.json"),
                 str(m.get("status", "unknown")), detail)


def _analysis(d: Path, rel: str) -> Entry:
    r = _load(d / "results.json")
    ks = r.get("joint_stiffness_Nm_per_rad") or []
    ci = r.get("ci95_Nm_per_rad") or [[None, None]] * len(ks)
    joints = r.get("joints_identified") or list(range(1, len(ks) + 1))
    k = [{"joint": j, "k_Nm_per_rad": v, "ci95_Nm_per_rad": c}
         for j, v, c in zip(joints, ks, ci, strict=False)]
    refused = r.get("refused") or r.get("refusals")
    warnings = r.get("warnings") or []
    accepted = (r.get("misfit_accepted") or {}).get("accepted") is True
    # a result written despite a refusal (--accept-misfit) says so, never "identified"
    status = ("refused" if refused else "accepted despite a refusal" if accepted
              else "identified, with warnings" if warnings else "identified")
    return Entry("analysis", rel, str(r.get("robot", "")), _mtime(d / "results.json"), status,
                 f"{r.get('method', '')}, {r.get('n_tests', '?')} tests", k)


#: files of an entry the page offers to open (read-only)
LINKED = ("report.html", "report.pdf", "summary.txt", "plan_map.png", "results.json",
          "model.toml")


def _with_files(e: Entry, d: Path) -> Entry:
    found = [f"{e.path}/{n}" if e.path else n for n in LINKED
             if (d / n).is_file() and not (d / n).is_symlink()]
    return Entry(**{**asdict(e), "files": found})


KINDS = (("plan", "summary.json", _plan), ("run", "metadata.json", _run),
         ("analysis", "results.json", _analysis))


def list_workspace(workspace: str | Path) -> list[Entry]:
    """Plans, runs and analyses under ``workspace``, newest first."""
    root = Path(workspace).resolve()
    out: list[Entry] = []
    for dirpath, dirnames, filenames in os.walk(root, followlinks=False):
        d = Path(dirpath)
        depth = len(d.relative_to(root).parts)
        dirnames[:] = sorted(n for n in dirnames if not n.startswith(".")
                             and depth < MAX_DEPTH and not (d / n).is_symlink())
        rel = d.relative_to(root).as_posix()
        for kind, marker, read in KINDS:
            if marker not in filenames or (marker == "summary.json"
                                           and "plan.csv" not in filenames):
                continue
            try:
                out.append(_with_files(read(d, rel), d))
            except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
                out.append(Entry(kind, rel, "", "", "unreadable",
                                 f"{marker}: {err}"))
        if len(out) >= MAX_ENTRIES:
            break
    out.sort(key=lambda e: e.date_utc, reverse=True)
    return out


def as_dicts(entries: list[Entry]) -> list[dict]:
    """JSON-ready entries."""
    return [asdict(e) for e in entries]
