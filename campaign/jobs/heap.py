"""The analyze job's memory handling, in one place: the garbage collector kept off the
imported modules' objects, and the heap pages a large import freed given back.

A 1e6-row analysis must stay under its peak memory target (docs/benchmarks.md) and the
demo's analysis with its report near its CPU target; these are the levers (with Arrow's
buffers kept on the C heap, :func:`arrow_on_c_heap`). Neither
changes a number the analysis computes.
"""

from __future__ import annotations

import atexit
import gc
from contextlib import contextmanager


@contextmanager
def frozen_heap():
    """Leave the objects alive now (mostly those of the imported modules: numpy, pandas,
    matplotlib, fpdf, about a million) out of the cyclic garbage collector's passes until
    the block ends; objects made inside are collected as usual. Each full collection
    would otherwise walk all of them again, about 0.1 s each and several per report."""
    gc.freeze()
    try:
        yield
        # Every output is written and closed: at interpreter exit, the objects alive then
        # are left to the operating system instead of being walked by the final collection
        # and torn down one by one (about 0.4 s for this process). The other exit handlers
        # still run and stdout/stderr are still flushed; __del__ is never promised at exit.
        atexit.unregister(gc.freeze)
        atexit.register(gc.freeze)
    finally:
        gc.unfreeze()


@contextmanager
def arrow_on_c_heap():
    """Arrow's buffers (the CSV reader's columns, pandas' Arrow-backed text, the CSV
    writers') from the C library's allocator until the block ends, so that
    :func:`release_freed_heap` gives their freed pages back too. Arrow's default pool
    (mimalloc) keeps them: ~60 MB resident through a 1e6-row analysis (measured), the
    difference between its peak and the target. Nothing is changed without pyarrow."""
    try:
        import pyarrow as pa
    except ImportError:
        yield
        return
    pool = pa.default_memory_pool()
    pa.set_memory_pool(pa.system_memory_pool())
    try:
        yield
    finally:
        pa.set_memory_pool(pool)


def freeze_imported() -> None:
    """Inside :func:`frozen_heap`: what was imported since joins the frozen objects (the
    identification's modules, the report's matplotlib)."""
    gc.freeze()


def release_freed_heap() -> None:
    """:func:`analysis.identification.streaming.per_test.release_freed_heap` (the text
    table's cells are many small allocations: freed, they stay in the process, ~0.15 GB
    after a 1e6-row import, under the arrays the fits then allocate)."""
    from analysis.identification.streaming.per_test import release_freed_heap as release

    release()
