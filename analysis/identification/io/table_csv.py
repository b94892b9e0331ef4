"""CSV files of large tables, byte for byte the text of pandas' ``DataFrame.to_csv(index=False)``.

pandas writes each float as numpy's shortest round-trip text (``str(np.float64)``:
``0.001``, ``1e-05``, ``2.0``, ``1e+16``, NaN as an empty cell), ``True``/``False``,
integers and text cells as they are, quoting (``"``) only a cell that holds a comma,
a quote or a line break. That text is made here a block of rows at a time by
Arrow's kernels, with ~6x less CPU than pandas (6e6 residual rows: ~7 s against
46 s). Arrow's float-to-text cast gives the same shortest digits but lays them
out differently for some magnitudes (``1e-7`` for
``1e-07``, ``0.00001`` for ``1e-05``, ``1`` for ``1.0``, ``1e+10`` for
``10000000000.0``); those cells are rewritten with string kernels, the rare ones
(1e10 <= |x| < 1e16) by numpy itself. Text cells go through Python's csv module once
per distinct value, with pandas' settings.

Columns taken: float64, integer, bool, text (str objects, pandas str/object
dtype) and categoricals of text. Any other column makes its block go through
pandas itself (the same bytes, only slower).
"""

from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Mapping
from pathlib import Path

import numpy as np
import pandas as pd

#: rows per block of :func:`write_frame` (a block's text is ~0.15 kB a row)
BLOCK_ROWS = 10_000


def _csv_line(cells: list[str]) -> str:
    """One row as pandas' csv writer writes it (QUOTE_MINIMAL, '"' doubled, os.linesep)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator=os.linesep).writerow(cells)
    return buf.getvalue()


def csv_cell(text: str) -> str:
    """A text cell as it appears in a row of two or more cells (quoted if it must be)."""
    return _csv_line([text, ""])[: -1 - len(os.linesep)]


def float_text(x: np.ndarray):
    """Arrow string array of ``x`` (float64) as pandas writes it: numpy's repr text, null for
    NaN (an empty cell)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    x = np.ascontiguousarray(x, dtype=np.float64)
    n = x.size
    s = pc.cast(pa.array(x, from_pandas=True), pa.string())
    ax = np.abs(x)
    parts, sel, off = [s], None, n

    def fix(mask: np.ndarray, make) -> None:
        nonlocal sel, off
        idx = np.flatnonzero(mask)
        if idx.size == 0:
            return
        if sel is None:
            sel = np.arange(n)
        parts.append(make(idx))
        sel[idx] = np.arange(off, off + idx.size)
        off += idx.size

    def shift(zeros: int, exponent: str, negative: bool, single: bool):
        # "[-]0.0000DDD" (Arrow, zeros after the point) -> "[-]D.DDe-05" (numpy)
        def make(idx):
            t = s.take(pa.array(idx))
            t = pc.binary_replace_slice(t, 0, 2 + zeros + negative, "-" if negative else "")
            if not single:
                t = pc.binary_replace_slice(t, 1 + negative, 1 + negative, ".")
            return pc.binary_join_element_wise(t, exponent, "")
        return make

    # the exponent of the shortest digits is that of x against the powers of ten as floats
    # (a shortest text d.dd x 10^k rounds to x, so x >= float(10^k) exactly when k is not
    # below): the classes below are exact
    with np.errstate(invalid="ignore"):
        integral = (ax < 1e10) & (x == np.trunc(x))
        fix(integral, lambda idx: pc.binary_join_element_wise(s.take(pa.array(idx)), ".0", ""))
        fix((ax >= 1e-9) & (ax < 1e-6),  # Arrow's e-7 .. e-9: numpy pads to two digits
            lambda idx: pc.replace_substring(s.take(pa.array(idx)), "e-", "e-0"))
        band = (ax >= 1e-6) & (ax < 1e-4)
        if band.any():
            length = pc.binary_length(s).to_numpy(zero_copy_only=False)
            neg = x < 0
            for zeros, exponent, low, high in ((5, "e-06", 1e-6, 1e-5), (4, "e-05", 1e-5, 1e-4)):
                inside = band & (ax >= low) & (ax < high)
                for negative in (False, True):
                    one = 2 + zeros + 1 + negative  # "0.00001": a single digit
                    part = inside & (neg == negative)
                    fix(part & (length == one), shift(zeros, exponent, negative, True))
                    fix(part & (length != one), shift(zeros, exponent, negative, False))
        # Arrow writes 1e10 .. 1e16 with an exponent, numpy in full: numpy's own text
        fix((ax >= 1e10) & (ax < 1e16), lambda idx: pa.array(x[idx].astype(str)))
    if sel is None:
        return s
    return pa.concat_arrays(parts).take(pa.array(sel))


def _cells(labels: list[str]):
    """(Arrow string array of the labels as cells, whether any needed quotes)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    cells = pa.array(labels, pa.string())
    # csv quotes a cell with a comma, a quote or a line break; these (and empty or
    # space-edged ones, a superset) go through the csv module, the rest are their own cell
    odd = np.flatnonzero(pc.match_substring_regex(cells, r'[,"\r\n]|^\s|\s$|^$').to_numpy(
        zero_copy_only=False))
    if odd.size == 0:
        return cells, False
    text = list(labels)
    for i in odd:
        text[i] = csv_cell(text[i])
    return pa.array(text, pa.string()), any(text[i] != labels[i] for i in odd)


def _labels_text(labels, codes: np.ndarray, memo: dict | None = None):
    """(Arrow string array of each code's label as a cell (null for code -1), whether any
    label needed quotes), or None when a label is not text. ``memo`` (a dict for this
    column, kept across the blocks of a table) holds the cells of its last categories."""
    import pyarrow as pa

    last = memo.get("labels") if memo is not None else None
    if last is not None and (last is labels or (len(last) == len(labels)
                                                and last.equals(labels))):
        cells, quoted = memo["cells"]
    else:
        labels_list = list(labels)
        if not all(isinstance(t, str) for t in labels_list):
            return None
        cells, quoted = _cells(labels_list)
        if memo is not None:
            memo.update(labels=labels, cells=(cells, quoted))
    codes = np.asarray(codes)
    return cells.take(pa.array(codes, mask=codes < 0)), quoted


def column_text(values, memo: dict | None = None):
    """(Arrow string array of a column's cells as pandas writes them, whether a cell is
    quoted), or None for a column this module does not take (pandas then writes it).
    ``memo``: a dict of this column kept across the blocks of a table (its categories'
    cells made once)."""
    import pyarrow as pa

    if isinstance(values, pd.Series):
        values = values.array if isinstance(values.dtype, pd.CategoricalDtype) else (
            values.to_numpy(dtype=object) if not isinstance(values.dtype, np.dtype)
            else values.to_numpy())
    if isinstance(values, pd.Categorical):
        return _labels_text(values.categories, values.codes, memo)
    values = np.asarray(values)
    kind = values.dtype.kind
    if values.dtype == np.float64:
        return float_text(values), False
    if kind in "iu":
        return pa.array(values).cast(pa.string()), False
    if kind == "b":
        return pa.array(["False", "True"]).take(pa.array(values.view(np.int8))), False
    if kind == "O":
        codes, uniques = pd.factorize(values)  # missing (None, NaN) as -1: an empty cell
        return _labels_text(list(uniques), codes)
    return None


def _block_bytes(columns: list, memo: dict | None = None) -> memoryview | None:
    """The CSV text of one block of columns (equal lengths), or None when a column is not
    taken."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv as pacsv

    memo = memo if memo is not None else {}
    texts = [column_text(c, memo.setdefault(j, {})) for j, c in enumerate(columns)]
    if any(t is None for t in texts):
        return None
    arrays = [t for t, _ in texts]
    if not any(q for _, q in texts) and os.linesep == "\n":
        # no cell needs quotes: Arrow's writer, unquoted (it refuses a cell that would need them)
        sink = pa.BufferOutputStream()
        pacsv.write_csv(pa.table(arrays, names=[f"c{j}" for j in range(len(arrays))]), sink,
                        pacsv.WriteOptions(include_header=False, quoting_style="none"))
        return memoryview(sink.getvalue())
    cells = [pc.fill_null(a, "") for a in arrays]
    cells[-1] = pc.binary_join_element_wise(cells[-1], "", os.linesep)
    rows = pc.binary_join_element_wise(*cells, ",")
    offsets = np.frombuffer(rows.buffers()[1], dtype=np.int32, count=len(rows) + 1,
                            offset=4 * rows.offset)
    return memoryview(rows.buffers()[2])[offsets[0]:offsets[-1]]


def write_blocks(path: str | Path, names: list[str],
                 blocks: Iterable[Mapping[str, object] | pd.DataFrame]) -> None:
    """Write a CSV file of the columns ``names`` from ``blocks`` (each a mapping of name to
    column, or a DataFrame), one after the other: the bytes of
    ``pd.concat(frames).to_csv(path, index=False)`` for frames of one dtype per column."""
    import pyarrow as pa

    memo: dict = {}
    # the C library's allocator for the blocks' Arrow buffers: Arrow's own pool keeps
    # ~30 MB more of the freed blocks in the process (measured, 6e6 rows)
    pool = pa.default_memory_pool()
    pa.set_memory_pool(pa.system_memory_pool())
    try:
        _write(path, names, blocks, memo)
    finally:
        pa.set_memory_pool(pool)


def _write(path, names: list[str], blocks, memo: dict) -> None:
    if len(names) < 2:
        raise ValueError("write_blocks takes two columns or more (csv quotes a lone empty cell)")
    from analysis.output_files import replacing

    with replacing(path) as tmp, open(tmp, "wb") as fh:
        fh.write(_csv_line([str(c) for c in names]).encode())
        for block in blocks:
            columns = [block[c] for c in names]
            if len(columns[0]) == 0:
                continue
            text = _block_bytes(columns, memo)
            if text is None:  # a column not taken here: pandas writes the block
                frame = block if isinstance(block, pd.DataFrame) else pd.DataFrame(
                    dict(zip(names, columns, strict=True)))
                text = frame.to_csv(index=False, header=False).encode()
            fh.write(text)


def write_frame(frame: pd.DataFrame, path: str | Path, block: int = BLOCK_ROWS) -> None:
    """``frame.to_csv(path, index=False)``, byte for byte, a block of rows at a time."""
    if len(frame.columns) < 2 or not frame.columns.is_unique:
        from analysis.output_files import replacing

        with replacing(path) as tmp:
            frame.to_csv(tmp, index=False)
        return
    write_blocks(path, list(frame.columns),
                 (frame.iloc[s:s + block] for s in range(0, len(frame), block)))
