"""The run directory of ``campaign acquire`` (contract: ``docs/run_format.md``).

Every append is one ``os.write`` of whole lines followed by ``os.fsync``, so a
crash (kill -9, power loss) leaves at worst one partial last line, which
:func:`repair_tail` cuts off before a resume. ``metadata.json`` is replaced
atomically (temporary file, fsync, rename, fsync of the directory).
"""

from __future__ import annotations

import csv
import fcntl
import io
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.measurements import CSV_COLUMNS

FORMAT_VERSION = 1
METADATA = "metadata.json"
SAMPLES = "samples.jsonl"
TESTS = "tests.csv"
EVENTS = "events.jsonl"
PLAN = "plan.csv"
LOCK = ".lock"

#: columns of tests.csv: the public CSV import format, then the run's own columns
TEST_COLUMNS = [*CSV_COLUMNS, "test_id", "repeat", "status", "flags", "repeatability_mm",
                "drift_mm", "wrench_error_N", "tracker_sigma_mm", "t_utc"]
STATUSES = ("running", "complete", "aborted", "failed")


def _jsonable(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` atomically (temp file, fsync, rename, fsync dir)."""
    tmp = path.with_name(f".{path.name}.tmp")
    with open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def repair_tail(path: Path) -> int:
    """Cut a partial last line (no final newline) left by a crash; returns bytes removed."""
    if not path.exists():
        return 0
    size = path.stat().st_size
    if size == 0:
        return 0
    with open(path, "rb+") as fh:
        fh.seek(max(0, size - 65536))
        tail = fh.read()
        if tail.endswith(b"\n"):
            return 0
        cut = tail.rfind(b"\n")
        keep = size - len(tail) + cut + 1 if cut >= 0 else (0 if size <= 65536 else size)
        fh.truncate(keep)
        fh.flush()
        os.fsync(fh.fileno())
    return size - keep


class Appender:
    """Append whole lines to a file with one write and an fsync each."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)

    def write(self, text: str) -> None:
        data = text.encode("utf-8")
        view = memoryview(data)
        while view:
            n = os.write(self._fd, view)
            view = view[n:]
        os.fsync(self._fd)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def format_row(row: dict[str, Any]) -> str:
    """One tests.csv line (columns :data:`TEST_COLUMNS`, full float precision)."""
    buf = io.StringIO()
    values = []
    for col in TEST_COLUMNS:
        v = row.get(col, "")
        if isinstance(v, (float, np.floating)):
            v = "" if not np.isfinite(v) else repr(float(v))
        elif isinstance(v, np.integer):
            v = int(v)
        values.append(v)
    csv.writer(buf, lineterminator="\n").writerow(values)
    return buf.getvalue()


class RunDir:
    """Writer of one run directory.

    Parameters
    ----------
    path : Path
        The run directory (created by :meth:`create`, reopened by :meth:`open`).
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.metadata: dict[str, Any] = {}
        self._samples: Appender | None = None
        self._tests: Appender | None = None
        self._events: Appender | None = None
        self._lock_fd = -1

    # -- creation and reopening ----------------------------------------------------------
    @classmethod
    def create(cls, path: Path, metadata: dict[str, Any], protocol_name: str,
               protocol_text: str, plan_text: str) -> RunDir:
        """Make a new run directory: metadata first, then the protocol and plan copies."""
        path = Path(path)
        if path.exists() and any(path.iterdir()):
            raise InputError("run directory exists and is not empty; use --resume to "
                             "continue it, or choose another --out", where=str(path))
        try:
            path.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise InputError(f"cannot create the run directory: {err.strerror}",
                             where=str(path)) from err
        run = cls(path)
        run.metadata = dict(metadata, format_version=FORMAT_VERSION, status="running",
                            reason="")
        run.write_metadata()
        atomic_write(path / protocol_name, protocol_text)
        atomic_write(path / PLAN, plan_text)
        run._open_appenders(new=True)
        return run

    @classmethod
    def open(cls, path: Path) -> RunDir:
        """Reopen an existing run for ``--resume``: repair partial lines, read metadata."""
        path = Path(path)
        meta_path = path / METADATA
        if not meta_path.is_file():
            raise InputError("not a run directory (no metadata.json)", where=str(path))
        try:
            metadata = json.loads(meta_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as err:
            raise InputError(f"cannot read metadata.json: {err}", where=str(meta_path)) from err
        if metadata.get("format_version") != FORMAT_VERSION:
            raise InputError(f"run format {metadata.get('format_version')!r} is not "
                             f"{FORMAT_VERSION}", where=str(meta_path))
        if not (path / PLAN).is_file():
            raise InputError("run directory lacks its plan.csv copy", where=str(path))
        for name in (SAMPLES, TESTS, EVENTS):
            repair_tail(path / name)
        run = cls(path)
        run.metadata = metadata
        run._open_appenders(new=not (path / TESTS).exists())
        return run

    def _lock(self) -> None:
        """Hold an exclusive lock on the run (released by the kernel even on kill -9)."""
        fd = os.open(self.path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise InputError("another campaign acquire is writing this run",
                             where=str(self.path)) from None
        self._lock_fd = fd

    def _open_appenders(self, new: bool) -> None:
        self._lock()
        tests_path = self.path / TESTS
        fresh = not tests_path.exists() or tests_path.stat().st_size == 0
        self._samples = Appender(self.path / SAMPLES)
        self._tests = Appender(tests_path)
        self._events = Appender(self.path / EVENTS)
        if fresh:
            self._tests.write(",".join(TEST_COLUMNS) + "\n")

    def close(self) -> None:
        for app in (self._samples, self._tests, self._events):
            if app is not None:
                app.close()
        if self._lock_fd >= 0:
            os.close(self._lock_fd)  # closing the descriptor releases the lock
            self._lock_fd = -1

    # -- records ----------------------------------------------------------------------------
    def write_metadata(self) -> None:
        atomic_write(self.path / METADATA,
                     json.dumps(self.metadata, indent=2, default=_jsonable) + "\n")

    def set_status(self, status: str, reason: str = "", **extra: Any) -> None:
        """Record the run's status (``running``, ``complete``, ``aborted``, ``failed``)."""
        if status not in STATUSES:
            raise ValueError(f"unknown status {status!r}")
        self.metadata.update(status=status, reason=reason, **extra)
        self.write_metadata()

    def sample(self, record: dict[str, Any]) -> None:
        """Append one raw reading to samples.jsonl (fsynced)."""
        self._samples.write(json.dumps(record, default=_jsonable) + "\n")

    def event(self, record: dict[str, Any]) -> None:
        """Append one event to events.jsonl (fsynced)."""
        self._events.write(json.dumps(record, default=_jsonable) + "\n")

    def test_row(self, row: dict[str, Any]) -> None:
        """Append one finished test to tests.csv (fsynced)."""
        self._tests.write(format_row(row))

    # -- reading back ----------------------------------------------------------------------
    def finished(self) -> set[tuple[int, int]]:
        """(test_id, repeat) pairs that already have a row in tests.csv."""
        return finished_tests(self.path)

    def export_parquet(self) -> None:
        """Write samples.parquet and tests.parquet (atomically) from the text tables."""
        export_parquet(self.path)


def read_tests(path: Path) -> pd.DataFrame:
    """tests.csv of run directory ``path`` as a DataFrame (empty if absent)."""
    f = Path(path) / TESTS
    if not f.exists() or f.stat().st_size == 0:
        return pd.DataFrame(columns=TEST_COLUMNS)
    return pd.read_csv(f, dtype={"pose": str, "status": str, "flags": str},
                       keep_default_na=True)


def finished_tests(path: Path) -> set[tuple[int, int]]:
    """(test_id, repeat) pairs with a row in tests.csv of run ``path``."""
    df = read_tests(path)
    return {(int(a), int(b)) for a, b in zip(df["test_id"], df["repeat"], strict=True)}


def read_samples(path: Path) -> pd.DataFrame:
    """samples.jsonl of run ``path`` as a DataFrame (a partial last line is skipped)."""
    rows = []
    f = Path(path) / SAMPLES
    if f.exists():
        with open(f, encoding="utf-8") as fh:
            for line in fh:
                if line.endswith("\n"):
                    rows.append(json.loads(line))
    return pd.DataFrame(rows)


def export_parquet(path: Path) -> None:
    """Parquet exports of tests.csv and samples.jsonl, each written atomically."""
    path = Path(path)
    for name, frame in (("tests.parquet", read_tests(path)),
                        ("samples.parquet", read_samples(path))):
        tmp = path / f".{name}.tmp"
        frame.to_parquet(tmp, index=False)
        os.replace(tmp, path / name)
    _fsync_dir(path)
