"""The run directory of ``campaign acquire`` (contract: ``docs/run_format.md``).

Every append is one ``os.write`` of whole lines followed by ``os.fsync``, so a
crash (kill -9, power loss) leaves at worst one partial last line, which
:func:`repair_tail` cuts off before a resume. ``metadata.json`` is replaced
atomically (temporary file, fsync, rename, fsync of the directory).
"""

from __future__ import annotations

import csv
import errno
import fcntl
import hashlib
import io
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.io.columns import CSV_COLUMNS, REF_W_COLS
from analysis.output_files import SymlinkRefused, refuse_link, refuse_links_in, replacing

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


def test_columns(metadata: dict[str, Any]) -> list[str]:
    """Columns of a run's tests.csv: :data:`TEST_COLUMNS`, then the reference wrench
    (:data:`~analysis.identification.io.columns.REF_W_COLS`) for a run whose load cases
    take their reference reading under a preload (metadata ``reference_wrench``)."""
    return [*TEST_COLUMNS, *REF_W_COLS] if metadata.get("reference_wrench") else TEST_COLUMNS


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


class WriteFailure(Exception):
    """A record of the run could not be written (disk full, read-only, ...).

    Not an :class:`OSError` on purpose: the runner tells a failed write of its
    own record apart from an instrument's socket error.
    """

    def __init__(self, path: Path, err: OSError) -> None:
        self.path, self.errno = Path(path), err.errno
        super().__init__(f"cannot write {self.path.name} in {self.path.parent}: "
                         f"{err.strerror or err}")


def atomic_write(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` atomically (temp file, fsync, rename, fsync dir).

    The temporary file has a name of its own per process and call, so two
    writers never share it; it is removed when the write fails.

    Raises
    ------
    WriteFailure
        The file could not be written (the old content is left in place).
    SymlinkRefused
        ``path`` is a symbolic link (never replaced, never written through).
    """
    refuse_link(path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    except OSError as err:  # an unwritable or read-only directory, a full disk
        raise WriteFailure(path, err) from err
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except OSError as err:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise WriteFailure(path, err) from err
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
        self._fd = _open_no_follow(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT)

    def write(self, text: str) -> None:
        """Append ``text`` (whole lines); :class:`WriteFailure` if it cannot be written.

        A failed write is cut back off (or, if even that fails, left as a partial
        line that :func:`repair_tail` cuts at resume), so the file keeps whole lines.
        """
        data = text.encode("utf-8")
        view = memoryview(data)
        size = -1
        try:
            size = os.fstat(self._fd).st_size
            while view:
                n = os.write(self._fd, view)
                view = view[n:]
            os.fsync(self._fd)
        except OSError as err:
            if size >= 0:
                try:
                    os.ftruncate(self._fd, size)
                except OSError:
                    pass
            raise WriteFailure(self.path, err) from err

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def _open_no_follow(path: Path, flags: int) -> int:
    """``os.open`` that never follows a symbolic link; :class:`SymlinkRefused` for a
    link, :class:`WriteFailure` when the file cannot be opened (read-only, permissions)."""
    try:
        return os.open(path, flags | os.O_NOFOLLOW, 0o644)
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise SymlinkRefused(path) from None
        raise WriteFailure(path, err) from err


def require_new_run_dir(path: Path) -> None:
    """Refuse ``path`` as a new run directory: a symbolic link (dangling or not), a file,
    a non-empty directory."""
    if os.path.islink(path):
        raise SymlinkRefused(path)
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise InputError("run directory exists and is not empty; use --resume to "
                         "continue it, or choose another --out", where=str(path))


def _remove_stale_creations(path: Path) -> None:
    """Remove ``.NAME.creating-*`` directories left by a creation that was killed.

    Only those whose lock can be taken: a creation still under way holds its lock.
    """
    for old in path.parent.glob(f".{path.name}.creating-*"):
        try:
            fd = os.open(old / LOCK, os.O_RDWR)
        except OSError:
            continue
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            continue
        else:
            shutil.rmtree(old, ignore_errors=True)
        finally:
            os.close(fd)


def read_metadata(path: Path) -> dict[str, Any]:
    """``metadata.json`` as a dict; an :class:`InputError` names the file when it is not one."""
    from analysis.file_errors import read_json_object

    return read_json_object(path, "metadata.json")


def sha256_file(path: Path) -> str:
    """SHA-256 (hex) of the bytes of ``path``."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def copy_mismatches(path: Path, metadata: dict[str, Any]) -> list[str]:
    """Copies in run ``path`` that no longer match the hash recorded when the run started.

    Returns one message per mismatching file (protocol copy, plan.csv); a hash the
    metadata does not hold (older runs) is not checked.
    """
    out = []
    copies = [p.name for p in sorted(Path(path).glob("protocol.*"))
              if p.suffix in (".toml", ".yaml", ".yml")]
    for name, key in ((copies[0] if copies else None, "protocol_sha256"),
                      (PLAN, "plan_sha256")):
        expected = metadata.get(key)
        if not name or not isinstance(expected, str) or not (path / name).is_file():
            continue
        try:
            digest = sha256_file(path / name)
        except OSError as err:
            out.append(f"{name}: cannot read: {err.strerror}")
            continue
        if digest != expected:
            out.append(f"{name} does not match {key} of metadata.json (sha256 {digest[:12]}... "
                       f"instead of {expected[:12]}...): the copy was changed after the run "
                       "started")
    return out


def verify_copies(path: Path, metadata: dict[str, Any]) -> None:
    """Refuse a run whose protocol or plan copy was changed after it started."""
    problems = copy_mismatches(path, metadata)
    if problems:
        raise InputError("; ".join(problems) + "; restore the original, or start a new run "
                         "with --plan", where=str(path))


def format_row(row: dict[str, Any], columns: list[str] = TEST_COLUMNS) -> str:
    """One tests.csv line (``columns``, default :data:`TEST_COLUMNS`; full float precision)."""
    buf = io.StringIO()
    values = []
    for col in columns:
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
        #: number of the acquire session writing now (1 = the first), in every record
        self.session: int | None = None
        self._samples: Appender | None = None
        self._tests: Appender | None = None
        self._events: Appender | None = None
        self._lock_fd = -1

    # -- creation and reopening ----------------------------------------------------------
    @classmethod
    def create(cls, path: Path, metadata: dict[str, Any], protocol_name: str,
               protocol_text: str, plan_text: str,
               beside: dict[str, Path] | None = None) -> RunDir:
        """Make a new run directory, atomically and exclusively.

        Everything (metadata, protocol and plan copies, tests.csv header, lock) is
        written in a temporary directory beside ``path``, which is then renamed to
        ``path``: a crash leaves either no run or a whole one (plus at worst a
        ``.NAME.creating-*`` directory, removed by the next creation), and of two
        processes creating the same run only one rename succeeds.
        """
        path = Path(path)
        require_new_run_dir(path)
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            _remove_stale_creations(path)
            tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.creating-", dir=path.parent))
            os.chmod(tmp, 0o755)
        except OSError as err:
            raise InputError(f"cannot create the run directory: {err.strerror}",
                             where=str(path)) from err
        run = cls(tmp)
        try:
            run.metadata = dict(metadata, format_version=FORMAT_VERSION, status="running",
                                reason="")
            run._open_appenders(new=True)
            run.write_metadata()
            atomic_write(tmp / protocol_name, protocol_text)
            atomic_write(tmp / PLAN, plan_text)
            from campaign.protocol_copy import copy_beside

            copy_beside(beside or {}, tmp)  # the protocol copy's robot file
            try:
                # POSIX rename replaces an empty directory and fails on a non-empty one
                os.rename(tmp, path)
            except OSError as err:
                raise InputError("run directory was created by another process meanwhile "
                                 f"({err.strerror}); choose another --out",
                                 where=str(path)) from None
        except BaseException as err:
            run.close()
            shutil.rmtree(tmp, ignore_errors=True)
            if isinstance(err, WriteFailure):
                raise InputError(f"cannot create the run directory: {err}",
                                 where=str(path)) from None
            raise
        run._moved_to(path)
        _fsync_dir(path.parent)
        return run

    @classmethod
    def open(cls, path: Path) -> RunDir:
        """Reopen an existing run for ``--resume``.

        Checks that the metadata is a readable object of this format, that the
        protocol and plan copies still match the hashes recorded at the start, and
        that tests.csv names each (test_id, repeat) once; then cuts partial last lines.
        """
        path = Path(path)
        refuse_links_in(path)  # before anything is read, repaired or appended to
        meta_path = path / METADATA
        if not meta_path.is_file():
            raise InputError("not a run directory (no metadata.json)", where=str(path))
        metadata = read_metadata(meta_path)
        if metadata.get("format_version") != FORMAT_VERSION:
            raise InputError(f"run format {metadata.get('format_version')!r} is not "
                             f"{FORMAT_VERSION}", where=str(meta_path))
        if not (path / PLAN).is_file():
            raise InputError("run directory lacks its plan.csv copy", where=str(path))
        if not isinstance(metadata.get("sessions", []), list):
            raise InputError("sessions: expected a list", where=str(meta_path))
        verify_copies(path, metadata)
        run = cls(path)
        run.metadata = metadata
        run._lock()  # before repairing: another process may be appending
        try:
            for name in (SAMPLES, TESTS, EVENTS):
                repair_tail(path / name)
            finished_tests(path)  # refuses a damaged or duplicated row before any motion
            run._open_appenders(new=not (path / TESTS).exists())
        except BaseException:
            run.close()
            raise
        return run

    def _moved_to(self, path: Path) -> None:
        self.path = path
        for app, name in ((self._samples, SAMPLES), (self._tests, TESTS),
                          (self._events, EVENTS)):
            if app is not None:
                app.path = path / name

    def _lock(self) -> None:
        """Hold an exclusive lock on the run (released by the kernel even on kill -9)."""
        fd = _open_no_follow(self.path / LOCK, os.O_RDWR | os.O_CREAT)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise InputError("another campaign acquire is writing this run",
                             where=str(self.path)) from None
        self._lock_fd = fd

    def _open_appenders(self, new: bool) -> None:
        if self._lock_fd < 0:
            self._lock()
        tests_path = self.path / TESTS
        fresh = not tests_path.exists() or tests_path.stat().st_size == 0
        self._samples = Appender(self.path / SAMPLES)
        self._tests = Appender(tests_path)
        self._events = Appender(self.path / EVENTS)
        if fresh:
            self._tests.write(",".join(test_columns(self.metadata)) + "\n")

    def close(self) -> None:
        """Close the files and release the lock; ``.lock`` is removed (while still held,
        so no other process is between its lock and our removal)."""
        for app in (self._samples, self._tests, self._events):
            if app is not None:
                app.close()
        if self._lock_fd >= 0:
            try:
                os.unlink(self.path / LOCK)
            except OSError:
                pass  # a read-only directory: the empty file stays, harmless
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
        self._tests.write(format_row(row, test_columns(self.metadata)))

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
    """(test_id, repeat) pairs with a row in tests.csv of run ``path``.

    A last line without its end of line (being written, or cut by a crash) is not
    a finished test. Raises :class:`InputError` naming the line of a row whose
    test_id or repeat is not a whole number, or of a (test_id, repeat) seen twice.
    """
    from analysis.file_errors import decode_utf8

    f = Path(path) / TESTS
    if not f.exists():
        return set()
    data = f.read_bytes()
    if not data.endswith(b"\n"):
        data = data[:data.rfind(b"\n") + 1]
    text = decode_utf8(data, str(f), "tests.csv")
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return set()
    header = [c.strip() for c in rows[0]]
    try:
        i_test, i_rep = header.index("test_id"), header.index("repeat")
    except ValueError:
        raise InputError("line 1: the header lacks test_id or repeat (see "
                         "docs/run_format.md); the run record is damaged", where=str(f)) from None
    seen: dict[tuple[int, int], int] = {}
    for line, row in enumerate(rows[1:], start=2):
        if not row:
            continue
        try:
            key = (_whole(row[i_test]), _whole(row[i_rep]))
        except (IndexError, ValueError, OverflowError):
            raise InputError(f"line {line}: not a test row ({len(row)} fields, test_id/repeat "
                             "not whole numbers); the run record is damaged: repair or remove "
                             "that line", where=str(f)) from None
        if key in seen:
            raise InputError(f"lines {seen[key]} and {line}: test {key[0]} repeat {key[1]} "
                             "recorded twice; the run record is damaged: keep one of them",
                             where=str(f))
        seen[key] = line
    return set(seen)


def _whole(text: str) -> int:
    value = float(text)
    if value != int(value):
        raise ValueError(text)
    return int(value)


def read_samples(path: Path) -> pd.DataFrame:
    """samples.jsonl of run ``path`` as a DataFrame (partial or damaged lines are skipped)."""
    rows = []
    f = Path(path) / SAMPLES
    if f.exists():
        with open(f, "rb") as fh:
            for line in fh:
                if not line.endswith(b"\n"):
                    continue
                try:
                    record = json.loads(line)
                except ValueError:  # a damaged line is not a reading
                    continue
                if isinstance(record, dict):
                    rows.append(record)
    return pd.DataFrame(rows)


def export_parquet(path: Path) -> None:
    """Parquet exports of tests.csv and samples.jsonl, each written atomically.

    A failed export (disk full, ...) leaves no temporary file behind.
    """
    path = Path(path)
    for name, frame in (("tests.parquet", read_tests(path)),
                        ("samples.parquet", read_samples(path))):
        with replacing(path / name) as tmp:
            frame.to_parquet(tmp, index=False)
    _fsync_dir(path)
