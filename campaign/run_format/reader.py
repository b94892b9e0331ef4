"""Read and check a run directory written by ``campaign acquire`` (``docs/run_format.md``).

A run is read as it is, finished or not: an ``aborted``, ``failed`` or still
``running`` status makes it a *partial* run, which is analysed from the tests
that finished (the report says so). Rows of ``tests.csv`` with ``status ==
failed`` are kept for the report with their data-quality flags but are not
used for identification. A truncated last line (the process was killed while
writing it) is dropped with a note when the run is not complete.

Every problem that prevents the analysis raises
:class:`analysis.errors.InputError` naming the file (and line, column or key).
Units: the tests table keeps the public CSV units (deg, N, N m, mm, mrad) and
the run's own columns (``repeatability_mm``, ``drift_mm``, ``wrench_error_N``,
``tracker_sigma_mm``); :attr:`Run.ok` is the tidy SI table used by
:func:`analysis.identification.estimate.analyze_table`.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.io.columns import CSV_COLUMNS, R_COLS, REF_W_COLS
from analysis.identification.io.csv_reader import from_csv_frame

FORMAT_VERSION = 1
STATUSES = ("running", "complete", "aborted", "failed")
TEST_STATUSES = ("ok", "failed")
KNOWN_FLAGS = ("drift", "repeatability", "saturation", "wrench_mismatch",
               "tracker_uncertainty", "retried")
RUN_COLUMNS = ["test_id", "repeat", "status", "flags", "repeatability_mm", "drift_mm",
               "wrench_error_N", "tracker_sigma_mm", "t_utc"]
QUALITY_COLUMNS = ["repeatability_mm", "drift_mm", "wrench_error_N", "tracker_sigma_mm"]
METADATA = "metadata.json"
TESTS = "tests.csv"


@dataclass
class Run:
    """A run directory as read (see the module docstring for units).

    Attributes
    ----------
    path : the run directory.
    metadata : ``metadata.json`` as a dict.
    status, reason : run status (``running``, ``complete``, ``aborted``, ``failed``) and why.
    protocol_path : the protocol copy in the run (None if absent).
    protocol_sha256 : SHA-256 of that copy (hex), None if absent.
    tests : every row of ``tests.csv`` (CSV units), with ``line`` (file line, header = 1)
        and ``flag_list`` (list of flags).
    ok : tidy SI table of the rows with status ``ok``
    (:mod:`analysis.identification.io.measurements`).
    events : ``events.jsonl`` records.
    notes : things the report must mention (hash mismatch, dropped line, unknown flags...).
    """

    path: Path
    metadata: dict
    status: str
    reason: str
    protocol_path: Path | None
    protocol_sha256: str | None
    tests: pd.DataFrame
    ok: pd.DataFrame
    events: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def partial(self) -> bool:
        """True unless the run finished (status ``complete``)."""
        return self.status != "complete"

    @property
    def n_planned(self) -> int | None:
        """Planned test rows (tests x repeats) from the metadata, None if unknown."""
        n = self.metadata.get("n_planned_tests")
        if not isinstance(n, int):
            return None
        repeats = self.metadata.get("repeats", 1)
        return n * (repeats if isinstance(repeats, int) and repeats > 0 else 1)

    @property
    def n_failed(self) -> int:
        return int((self.tests["status"] == "failed").sum())

    def flagged(self) -> pd.DataFrame:
        """Rows with a flag or a failed status (CSV units)."""
        mask = (self.tests["status"] == "failed") | self.tests["flag_list"].map(bool)
        return self.tests[mask]

    def flag_counts(self) -> dict[str, int]:
        """Number of rows carrying each flag (all flags seen, known ones first)."""
        counts: dict[str, int] = {}
        for flags in self.tests["flag_list"]:
            for f in flags:
                counts[f] = counts.get(f, 0) + 1
        order = [f for f in KNOWN_FLAGS if f in counts] + sorted(set(counts) - set(KNOWN_FLAGS))
        return {f: counts[f] for f in order}


def _check_metadata(meta: dict, where: str) -> None:
    version = meta.get("format_version")
    if version != FORMAT_VERSION:
        raise InputError(f"format_version {version!r}: this program reads version "
                         f"{FORMAT_VERSION}", where=f"{where}: format_version")
    status = meta.get("status")
    if status not in STATUSES:
        raise InputError(f"status {status!r}: expected one of {', '.join(STATUSES)}",
                         where=f"{where}: status")


def _read_events(path: Path, notes: list[str]) -> list[dict]:
    if not path.is_file():
        return []
    events = []
    for i, line in enumerate(path.read_bytes().splitlines(), start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except ValueError:  # not JSON, or not UTF-8
            record = None
        if isinstance(record, dict):
            events.append(record)
        else:
            notes.append(f"{path.name} line {i}: not a JSON object, skipped")
    return events


def _load_notes(events: list[dict]) -> list[str]:
    """Loud notes when a session ended with the load still on the tool."""
    out = []
    for e in events:
        if e.get("event") == "load_left":
            session = e.get("session")
            out.append(f"WARNING: the load was left applied at the end of "
                       f"{'session ' + str(session) if session else 'a session'} "
                       f"(test {e.get('test_id')}, repeat {e.get('repeat')}): "
                       f"{e.get('reason') or 'see events.jsonl'}")
    return out


def _protocol_file(run: Path, meta: dict) -> Path | None:
    for name in ("protocol.toml", "protocol.yaml", "protocol.yml"):
        if (run / name).is_file():
            return run / name
    return None


def _read_tests_text(path: Path, partial: bool, notes: list[str]) -> pd.DataFrame:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise InputError(f"cannot read: {err.strerror}", where=str(path)) from err
    except UnicodeDecodeError as err:
        raise InputError("not UTF-8 text", where=str(path)) from err
    lines = text.splitlines()
    if text and not text.endswith("\n") and len(lines) > 1:
        if not partial:
            raise InputError(f"line {len(lines)}: last line is incomplete (no end of line)",
                             where=str(path))
        notes.append(f"{path.name} line {len(lines)} was being written when the run stopped: "
                     "dropped")
        lines = lines[:-1]
    if not lines:
        raise InputError("empty file: no header", where=str(path))
    import io

    try:
        frame = pd.read_csv(io.StringIO("\n".join(lines) + "\n"), dtype=str,
                            skipinitialspace=True, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as err:
        raise InputError(f"not a CSV table ({str(err).strip()}); the run record is damaged",
                         where=str(path)) from None
    frame.columns = [str(c).strip() for c in frame.columns]
    missing = [c for c in CSV_COLUMNS + RUN_COLUMNS if c not in frame.columns]
    if missing:
        raise InputError(f"missing column(s) {', '.join(missing)} (see docs/run_format.md)",
                         where=str(path))
    frame["line"] = np.arange(len(frame)) + 2
    return frame


def _check_keys(frame: pd.DataFrame, where: str) -> None:
    """test_id and repeat are whole numbers, and each (test_id, repeat) is one row."""
    keys = {}
    for col in ("test_id", "repeat"):
        raw = frame[col].astype(str).str.strip()
        values = pd.to_numeric(raw, errors="coerce").to_numpy(dtype=float)
        bad = ~np.isfinite(values) | (values != np.round(values))
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(f"line {frame['line'].iloc[i]}, column {col}: {raw.iloc[i]!r} is "
                             "not a whole number; the run record is damaged", where=where)
        keys[col] = values.astype(np.int64)
    seen: dict[tuple[int, int], int] = {}
    for t, r, line in zip(keys["test_id"], keys["repeat"], frame["line"], strict=True):
        if (t, r) in seen:
            raise InputError(f"lines {seen[(t, r)]} and {line}: test {t} repeat {r} recorded "
                             "twice (each measurement must be counted once); the run record "
                             "is damaged: keep one of the rows", where=where)
        seen[(t, r)] = line


def _check_cells(frame: pd.DataFrame, where: str) -> None:
    """Status values, and numbers in the columns identification needs (ok rows)."""
    for i, status in enumerate(frame["status"].str.strip()):
        if status not in TEST_STATUSES:
            raise InputError(f"line {frame['line'].iloc[i]}, column status: {status!r} "
                             f"(expected ok or failed)", where=where)
    ok = frame[frame["status"].str.strip() == "ok"]
    required = [c for c in CSV_COLUMNS[1:] if c not in R_COLS]
    for col in required + R_COLS + QUALITY_COLUMNS:
        raw = ok[col].astype(str).str.strip()
        values = pd.to_numeric(raw, errors="coerce")
        empty = raw == ""
        bad = values.isna() & ~empty
        if col in required:
            bad |= empty
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            what = "empty" if raw.iloc[i] == "" else f"{raw.iloc[i]!r} is not a number"
            raise InputError(f"line {ok['line'].iloc[i]}, column {col}: {what}", where=where)


def _flags(frame: pd.DataFrame, notes: list[str]) -> list[list[str]]:
    out = []
    unknown: set[str] = set()
    for text in frame["flags"].astype(str):
        flags = [f.strip() for f in text.split(";") if f.strip()]
        unknown.update(f for f in flags if f not in KNOWN_FLAGS)
        out.append(flags)
    if unknown:
        notes.append(f"unknown data-quality flag(s) {', '.join(sorted(unknown))} (shown as is)")
    return out


def _to_si(frame: pd.DataFrame, where: str) -> pd.DataFrame:
    ok = frame[frame["status"] == "ok"]
    if ok.empty:
        raise InputError("no test finished with status ok: nothing to identify from",
                         where=where)
    csv = ok[CSV_COLUMNS + [c for c in REF_W_COLS if c in ok.columns]].reset_index(drop=True)
    try:
        table = from_csv_frame(csv, where=where)
    except InputError as err:
        # from_csv_frame counts lines within the ok rows; say which rows those are.
        lines = ", ".join(str(v) for v in ok["line"])
        raise InputError(f"{err} (lines counted among the ok rows, file lines {lines})") from None
    table["line"] = ok["line"].to_numpy()
    return table


#: line numbers of damaged lines listed in a message, at most
LINES_LISTED = 5


def _damaged_samples(path: Path) -> tuple[list[int], bool]:
    """(line numbers (1-based) of ``samples.jsonl`` that are not a JSON object (a line cut
    short by a crash, a disk error, an edit; blank lines are not counted), True when the
    last of them is the file's unfinished last line (no end of line))."""
    bad, line = [], b"\n"
    with open(path, "rb") as fh:
        for i, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
            except ValueError:  # not JSON, or not UTF-8
                record = None
            if not isinstance(record, dict):
                bad.append(i)
    return bad, bool(bad) and bad[-1] == i and not line.endswith(b"\n")


def _check_samples(run: Path, partial: bool, notes: list[str]) -> list[int]:
    """Damaged lines of the run's ``samples.jsonl``: a WARNING note when any, but a plain
    note for the unfinished last line of a run that stopped (as for tests.csv)."""
    path = run / "samples.jsonl"
    if not path.is_file():
        return []
    try:
        bad, cut_last = _damaged_samples(path)
    except OSError as err:
        notes.append(f"WARNING: {path.name}: cannot read ({err.strerror or err}): the raw "
                     "readings were not checked")
        return []
    loud = bad
    if partial and cut_last:
        notes.append(f"{path.name} line {bad[-1]} was being written when the run stopped: "
                     "dropped")
        loud = bad[:-1]
    if loud:
        listed = ", ".join(str(i) for i in loud[:LINES_LISTED]) + (
            f" and {len(loud) - LINES_LISTED} more" if len(loud) > LINES_LISTED else "")
        notes.append(f"WARNING: {path.name}: {len(loud)} damaged line(s) (not a JSON object: "
                     f"line {listed}), skipped; the raw readings on them are lost (the "
                     "analysis uses tests.csv, which is not affected)")
    return bad


def _export_parquet(run: Path, tests: pd.DataFrame, notes: list[str],
                    damaged: list[int] = ()) -> None:
    """Write ``tests.parquet`` and ``samples.parquet`` when missing (docs/run_format.md);
    the ``damaged`` lines of samples.jsonl are left out."""
    from analysis.output_files import replacing

    try:
        if not os.path.lexists(run / "tests.parquet"):
            with replacing(run / "tests.parquet") as tmp:
                tests.drop(columns=["flag_list"]).to_parquet(tmp, index=False)
        samples = run / "samples.jsonl"
        if samples.is_file() and not os.path.lexists(run / "samples.parquet"):
            source = samples
            if damaged:
                import io

                skip = set(damaged)
                with open(samples, "rb") as fh:
                    good = b"".join(line for i, line in enumerate(fh, start=1)
                                    if i not in skip and line.strip())
                source = io.StringIO(good.decode("utf-8"))
            table = pd.read_json(source, lines=True)
            if len(table):
                with replacing(run / "samples.parquet") as tmp:
                    table.to_parquet(tmp, index=False)
    except (OSError, ValueError, ImportError) as err:
        notes.append(f"could not write the Parquet exports into the run: {err}")


def read_run(path: str | Path, export: bool = True) -> Run:
    """Read the run directory ``path``; see the module docstring.

    Parameters
    ----------
    path : run directory (``metadata.json``, ``tests.csv``, protocol copy, ...).
    export : write ``tests.parquet``/``samples.parquet`` into the run when missing.

    Raises
    ------
    InputError
        Not a directory, metadata missing or invalid, ``tests.csv`` missing or
        malformed, no ok test.
    """
    run = Path(path)
    if not run.is_dir():
        raise InputError("run directory not found", where=str(run))
    meta_path = run / METADATA
    if not meta_path.is_file():
        raise InputError(f"no {METADATA}: not a run directory (see docs/run_format.md)",
                         where=str(run))
    from analysis.file_errors import read_json_object

    meta = read_json_object(meta_path, meta_path.name)
    _check_metadata(meta, str(meta_path))
    status = meta["status"]
    notes: list[str] = []
    tests_path = run / TESTS
    if not tests_path.is_file():
        raise InputError(f"no {TESTS}: the run (status {status}) finished no test",
                         where=str(run))
    frame = _read_tests_text(tests_path, status != "complete", notes)
    frame["status"] = frame["status"].str.strip()
    _check_keys(frame, str(tests_path))
    _check_cells(frame, str(tests_path))
    frame["flag_list"] = _flags(frame, notes)
    for col in QUALITY_COLUMNS:
        frame[col] = pd.to_numeric(frame[col], errors="coerce")
    ok = _to_si(frame, str(tests_path))
    proto = _protocol_file(run, meta)
    digest = None
    if proto is not None:
        digest = hashlib.sha256(proto.read_bytes()).hexdigest()
        expected = meta.get("protocol_sha256")
        if expected and expected != digest:
            # the robot, tool and noise come from this copy: a changed one changes k
            raise InputError(f"{proto.name} does not match protocol_sha256 of metadata.json "
                             "(the copy was changed after the run started): restore the "
                             "original; to analyse with other figures use the options "
                             "--translation-sigma-um, --rotation-sigma-urad, --force-sigma-N "
                             "and --moment-sigma-Nm, or import tests.csv with --measurements",
                             where=str(run))
    plan_sha = meta.get("plan_sha256")
    if isinstance(plan_sha, str) and (run / "plan.csv").is_file():
        # the plan is not used by the analysis, so this is said loudly, not refused
        if hashlib.sha256((run / "plan.csv").read_bytes()).hexdigest() != plan_sha:
            notes.append("WARNING: plan.csv does not match plan_sha256 of metadata.json: the "
                         "copy was changed after the run started (not used by the analysis)")
    damaged = _check_samples(run, status != "complete", notes)
    if export:
        _export_parquet(run, frame, notes, damaged)
    events = _read_events(run / "events.jsonl", notes)
    notes.extend(_load_notes(events))
    return Run(path=run, metadata=meta, status=status, reason=str(meta.get("reason") or ""),
               protocol_path=proto, protocol_sha256=digest, tests=frame, ok=ok,
               events=events, notes=notes)
