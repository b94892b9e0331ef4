"""Reading a tests CSV file (the public format of :mod:`analysis.identification.io.columns`)
into the tidy SI table (:func:`read_csv`) or straight into
:class:`~analysis.identification.io.measurements.TestArrays` (:func:`read_test_arrays`,
streamed by Arrow). Every error names the CSV line (header = line 1) and the column at
fault.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.io.columns import CSV_COLUMNS, N_JOINTS, REF_W_COLS, TO_SI
from analysis.identification.io.measurements import TestArrays, to_arrays
from analysis.identification.io.table_checks import validate_arrays, validate_table


def _numeric(frame: pd.DataFrame, col: str, where: str, line0: int) -> np.ndarray:
    raw = frame[col]
    if pd.api.types.is_numeric_dtype(raw.dtype) and not pd.api.types.is_bool_dtype(raw.dtype):
        return raw.to_numpy(dtype=float)  # parsed as numbers already (fast path of read_csv)
    values = pd.to_numeric(raw, errors="coerce")
    text = raw.astype(str).str.strip()
    bad = values.isna() & raw.notna() & (text != "") & (text.str.lower() != "nan")
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(
            f"line {i + line0}, column {col}: {raw.iloc[i]!r} is not a number", where=where
        )
    return values.to_numpy(dtype=float)


def read_csv(path: str | Path) -> pd.DataFrame:
    """Read a tests CSV file (public format) into the tidy SI table.

    Raises
    ------
    InputError
        File missing or unreadable, a column missing, a non-numeric or empty
        required cell, a non-finite number, a partial rotation triple; the
        message names the file, the line and the column.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("measurements file not found", where=str(path))
    frame = _read_numeric(path)
    if frame is not None:
        return from_csv_frame(frame, where=str(path))
    try:
        frame = pd.read_csv(path, dtype=str, skipinitialspace=True, keep_default_na=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise InputError(f"cannot read as CSV: {err}", where=str(path)) from err
    return from_csv_frame(frame, where=str(path))


#: cells read as "not measured" by the fast path; the text path accepts the same
#: (empty, or "nan" in any case, after stripping)
_NA_TEXT = ["", "nan", "NaN", "NAN", "Nan", "nAn", "naN", "NAn", "nAN"]


def _read_numeric(path: Path) -> pd.DataFrame | None:
    """The CSV with its numeric columns parsed by the C reader, or None when any cell
    is not a plain number (the text path then finds and names it).

    Parsing every cell as text first costs ~10x for large files (1e6 rows), so
    the common well-formed file goes straight to floats.
    """
    try:
        frame = pd.read_csv(path, skipinitialspace=True, keep_default_na=False,
                            na_values={c: _NA_TEXT for c in CSV_COLUMNS[1:]},
                            dtype={"pose": str}, engine="c", low_memory=False)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, ValueError,
            OSError):
        return None
    frame = frame.rename(columns=lambda c: str(c).strip())
    if len(frame) == 0 or any(c not in frame.columns for c in CSV_COLUMNS):
        return None
    for col in CSV_COLUMNS[1:]:
        dtype = frame[col].dtype
        if not pd.api.types.is_numeric_dtype(dtype) or pd.api.types.is_bool_dtype(dtype):
            return None
    return frame


def read_test_arrays(path: str | Path) -> TestArrays:
    """Read a tests CSV file (public format) straight into :class:`TestArrays` (SI).

    The same tests, checks and messages as ``to_arrays(read_csv(path))``, with a
    fraction of the memory: the file is streamed by Arrow's CSV reader in blocks
    of 256 kB into the final arrays, so nothing but those arrays stays (a 1e6-test
    file: ~0.2 GB above the imports at the peak, against ~0.55 GB for the table
    route). Equal pose labels share one string object. A file Arrow cannot take as plain numbers (a
    non-numeric cell, spaces around a number, a row of the wrong length, ...) goes
    through :func:`read_csv`, whose text path finds and names the cell.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("measurements file not found", where=str(path))
    tests = _read_arrow(path)
    if tests is None:
        tests = to_arrays(read_csv(path))
        codes, labels = pd.factorize(tests.pose)  # one string object per distinct label
        tests = replace(tests, pose=np.asarray(labels, dtype=object)[codes])
    return tests


#: bytes per block of the streamed reader (~1000 rows of the public format): blocks this
#: small keep the reader's own buffers out of the peak memory
_BLOCK_BYTES = 1 << 18


def _count_lines(path: Path) -> int:
    """Newlines in the file, plus one for a last line without: a bound on the rows."""
    n, last = 0, b"\n"
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            n += chunk.count(b"\n")
            last = chunk[-1:]
    return n + (last != b"\n")


def _header(path: Path) -> list[str] | None:
    """The header's cells (stripped), or None when the first line is not readable text."""
    import csv

    try:
        with open(path, encoding="utf-8", newline="") as fh:
            return [c.strip() for c in next(csv.reader(fh))]
    except (UnicodeDecodeError, csv.Error, StopIteration, OSError):
        return None


def _read_arrow(path: Path) -> TestArrays | None:
    """The tests of a well-formed file read by Arrow, or None for :func:`read_csv` to read
    (and name what is wrong). Raises the :func:`from_csv_frame` errors of a file
    Arrow reads (empty pose label, non-finite, implausible, partial rotation, zero
    wrench)."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    names = _header(path)
    if names is None or any(names.count(c) != 1 for c in CSV_COLUMNS) or any(
            c in names for c in REF_W_COLS):  # the reference wrench: the table route
        return None  # missing or repeated columns: read_csv says which
    # columns by position: the header's own spelling (spaces, quotes) no longer matters
    keys = [f"c{j}" for j in range(len(names))]
    key = {c: keys[names.index(c)] for c in CSV_COLUMNS}
    numeric = CSV_COLUMNS[1:]
    options = {
        "read_options": pacsv.ReadOptions(column_names=keys, skip_rows=1,
                                          block_size=_BLOCK_BYTES, use_threads=False),
        "convert_options": pacsv.ConvertOptions(
            include_columns=[key[c] for c in CSV_COLUMNS],
            column_types={key["pose"]: pa.string(), **{key[c]: pa.float64() for c in numeric}},
            null_values=_NA_TEXT, strings_can_be_null=False),
    }
    cap = max(_count_lines(path) - 1, 0)  # the rows, unless blank lines or breaks in cells
    # the final arrays, filled block by block; column-major, as the table route makes them
    # (the fits' sums then add in the same order: the same results to the last bit)
    q, w, d = (np.empty((cap, N_JOINTS), order="F") for _ in range(3))
    target = [(block, k) for block in (q, w, d) for k in range(N_JOINTS)]
    codes = np.empty(cap, dtype=np.int32)
    labels: dict[str, int] = {}
    m = 0
    try:
        reader = pacsv.open_csv(path, memory_pool=pa.system_memory_pool(), **options)
        for batch in reader:
            n = batch.num_rows
            if m + n > cap:
                return None
            # pose labels: the block's distinct labels, stripped, numbered across the file
            enc = batch.column(key["pose"]).dictionary_encode()
            local = np.array([labels.setdefault(t.strip(), len(labels))
                              for t in enc.dictionary.to_pylist()], dtype=np.int32)
            codes[m:m + n] = local[enc.indices.to_numpy(zero_copy_only=False)]
            for j, c in enumerate(numeric):
                col = batch.column(key[c])
                v = col.to_numpy(zero_copy_only=False)  # nulls (empty, "nan") as NaN
                # NaN or inf spelled otherwise ("-nan", "inf"): the text path decides
                if np.count_nonzero(np.isfinite(v)) != n - col.null_count:
                    return None
                block, k = target[j]
                block[m:m + n, k] = v * TO_SI[c][1]
            m += n
    except (pa.ArrowInvalid, pa.ArrowNotImplementedError, UnicodeDecodeError, OSError):
        return None
    if m == 0:
        return None  # header only: read_csv says so
    if m < cap:  # blank lines: the arrays of the rows read
        q, w, d = (np.asfortranarray(a[:m]) for a in (q, w, d))
    codes = codes[:m]
    where = str(path)
    bad = [labels[t] for t in ("", "nan", "None") if t in labels]
    if bad:
        i = int(np.flatnonzero(np.isin(codes, bad))[0])
        raise InputError(f"line {i + 2}, column pose: empty pose label", where=where)
    line = np.arange(m, dtype=np.int64) + 2
    validate_arrays(q, w, d, line, where)
    pose = np.empty(len(labels), dtype=object)
    pose[:] = list(labels)
    return TestArrays(pose=pose[codes], q=q, w=w, d=d, measured=np.isfinite(d), line=line)


def _reference_wrench(frame: pd.DataFrame, out: pd.DataFrame, where: str, line0: int) -> None:
    """The optional reference-wrench columns (N, N m) into ``out``: all six or none; a
    row with all six empty has an unloaded reference (0), a partly empty one is refused."""
    present = [c for c in REF_W_COLS if c in frame.columns]
    if not present:
        return
    if len(present) < len(REF_W_COLS):
        missing = [c for c in REF_W_COLS if c not in frame.columns]
        raise InputError(f"reference wrench: column(s) {', '.join(missing)} missing; give all "
                         f"of {', '.join(REF_W_COLS)} or none", where=where)
    text = frame[REF_W_COLS].astype(str).apply(lambda c: c.str.strip())
    empty = text.isin(_NA_TEXT).to_numpy()
    partial = empty.any(axis=1) & ~empty.all(axis=1)
    if partial.any():
        i = int(np.flatnonzero(partial)[0])
        raise InputError(f"line {i + line0}: reference wrench partly empty (give all six "
                         "components, or leave all six empty for an unloaded reference)",
                         where=where)
    for j, col in enumerate(REF_W_COLS):
        values = np.array(_numeric(frame, col, where, line0), dtype=float)
        values[empty[:, j]] = 0.0
        if not np.all(np.isfinite(values)):
            i = int(np.flatnonzero(~np.isfinite(values))[0])
            raise InputError(f"line {i + line0}, column {col}: not a finite number",
                             where=where)
        out[col] = values


def from_csv_frame(frame: pd.DataFrame, where: str = "measurements") -> pd.DataFrame:
    """Convert a frame with the public CSV columns (deg, mm, mrad) to the tidy SI table.

    Row i of ``frame`` is reported as CSV line i + 2 (the header is line 1).
    """
    frame = frame.rename(columns=lambda c: str(c).strip())
    missing = [c for c in CSV_COLUMNS if c not in frame.columns]
    if missing:
        raise InputError(
            f"missing column(s) {', '.join(missing)}; expected the columns "
            f"{', '.join(CSV_COLUMNS)} (rotation columns may be left empty)",
            where=where,
        )
    if len(frame) == 0:
        raise InputError("no tests: the file has a header but no rows", where=where)
    line0 = 2
    out = pd.DataFrame({"pose": frame["pose"].astype(str).str.strip().to_numpy()})
    empty_pose = out["pose"].isin(["", "nan", "None"])
    if empty_pose.any():
        i = int(np.flatnonzero(empty_pose.to_numpy())[0])
        raise InputError(f"line {i + line0}, column pose: empty pose label", where=where)
    for col in CSV_COLUMNS[1:]:
        si, factor = TO_SI[col]
        out[si] = _numeric(frame, col, where, line0) * factor
    _reference_wrench(frame, out, where, line0)
    out["line"] = np.arange(len(frame)) + line0
    validate_table(out, where=where)
    return out
