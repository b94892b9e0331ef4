"""The residual table of an identification held as per-test arrays, made into rows a block
of tests at a time (residuals.csv, the rows results.json lists)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.identification.io.columns import COMPONENTS
from analysis.identification.io.measurements import TestArrays

#: bin edges of the histogram of studentized residuals in results.json
HISTOGRAM_EDGES = np.array([-np.inf, -6, -5, -4, -3, -2, -1, 0, 1, 2, 3, 4, 5, 6, np.inf])


def histogram(t: np.ndarray) -> dict:
    """Counts of the studentized residuals ``t`` in :data:`HISTOGRAM_EDGES` (results.json)."""
    finite = np.isfinite(t)
    counts, _ = np.histogram(t[finite], HISTOGRAM_EDGES)
    edges = [None if not math.isfinite(e) else float(e) for e in HISTOGRAM_EDGES]
    return {"studentized_edges": edges, "counts": counts.tolist(),
            "not_finite": int((~finite).sum())}


@dataclass(frozen=True)
class ResidualRows:
    """The residual table held as per-test arrays, made into rows a block of tests at a time.

    ``tests`` the tests analysed; ``predicted``, ``sigma`` (model sigma of each
    component, or a :class:`~analysis.identification.streaming.per_test.PerTestSigma` made for the
    tests written; else
    component), ``t`` (studentized residual) (m, 6); ``flags`` (m, 6) bool, the residuals
    the fit set aside (the sequential outlier test's refits, or a robust fit's
    down-weighted ones): column ``set_aside``; ``threshold``: the stated outlier
    threshold, column ``outlier`` = |t| beyond it (so the ``outlier`` rows are exactly
    the residuals beyond the threshold, whatever the procedure set aside);
    ``weights`` (m, 6) robust weights or None. A 1e6-test campaign has 6e6 rows (~0.4 GB
    as a DataFrame): its full table is only ever made in blocks, for residuals.csv.
    """

    tests: TestArrays
    predicted: np.ndarray
    sigma: np.ndarray
    t: np.ndarray
    flags: np.ndarray
    weights: np.ndarray | None = None
    threshold: float = float("inf")

    def __post_init__(self) -> None:
        # pose labels as category codes and the categoricals' dtypes, once (every block of
        # rows uses them; a dtype made per block would check 1e5 categories each time)
        from analysis.identification.poses import factorize_labels

        codes, labels = factorize_labels(self.tests.pose)
        dtypes = {"pose": pd.CategoricalDtype(labels),
                  "component": pd.CategoricalDtype(COMPONENTS),
                  "unit": pd.CategoricalDtype(["m", "rad"])}
        object.__setattr__(self, "_pose_codes", (codes, dtypes))

    @property
    def n_rows(self) -> int:
        return int(self.tests.measured.sum())

    @property
    def n_tests(self) -> int:
        """Tests with at least one measured component (one row or more)."""
        return int(self.tests.measured.any(axis=1).sum())

    #: the columns of the table, in order
    COLUMNS = ("test", "line", "pose", "component", "unit", "measured", "predicted",
               "residual", "sigma", "studentized", "outlier", "set_aside")

    @property
    def names(self) -> list[str]:
        """The table's column names (``weight`` last for a robust fit)."""
        return [*self.COLUMNS, *(["weight"] if self.weights is not None else [])]

    def columns(self, which: np.ndarray | slice = slice(None)) -> dict:
        """Columns (arrays; text as categoricals) of the rows of the tests ``which`` (sorted
        indices or a slice): one per test and measured component, tests in order,
        components in order."""
        tests = self.tests
        idx = np.arange(tests.m)[which]
        meas = tests.measured[idx]
        k, c = np.nonzero(meas)  # row-major: by test, then component
        i = idx[k]
        # text columns as categoricals: millions of Python strings would take ~1 GB
        codes, dtypes = self._pose_codes
        measured = tests.d[i, c]
        predicted = self.predicted[i, c]
        out = {
            "test": i.astype(np.int64), "line": tests.line[i].astype(np.int64),
            "pose": pd.Categorical.from_codes(codes[i], dtype=dtypes["pose"]),
            "component": pd.Categorical.from_codes(c, dtype=dtypes["component"]),
            "unit": pd.Categorical.from_codes((c >= 3).astype(np.int8), dtype=dtypes["unit"]),
            "measured": measured, "predicted": predicted,
            "residual": measured - predicted, "sigma": (
                self.sigma[i, c] if isinstance(self.sigma, np.ndarray)
                else self.sigma.take(idx)[k, c]),  # made for these tests
            "studentized": self.t[i, c], "outlier": self.beyond(i, c),
            "set_aside": self.flags[i, c].astype(bool),
        }
        if self.weights is not None:
            out["weight"] = self.weights[i, c]
        return out

    def beyond(self, i, c) -> np.ndarray:
        """bool: |studentized residual| of rows (i, c) beyond :attr:`threshold` (NaN: no)."""
        with np.errstate(invalid="ignore"):
            return np.abs(self.t[i, c]) > self.threshold

    def n_beyond(self, block: int = 1 << 16) -> int:
        """Measured residuals with |studentized| beyond :attr:`threshold` (all rows)."""
        with np.errstate(invalid="ignore"):
            return int(sum(int(np.sum(self.tests.measured[s:s + block]
                                      & (np.abs(self.t[s:s + block]) > self.threshold)))
                           for s in range(0, self.tests.m, block)))

    def marked(self, rows=slice(None)) -> np.ndarray:
        """(m, 6) bool of the tests ``rows``: beyond the threshold or set aside."""
        with np.errstate(invalid="ignore"):
            return self.flags[rows] | (np.abs(self.t[rows]) > self.threshold)

    def frame(self, which: np.ndarray | slice = slice(None)) -> pd.DataFrame:
        """:meth:`columns` as a DataFrame."""
        return pd.DataFrame(self.columns(which))

    def blocks(self, block: int = 1_000):
        """The whole table as :meth:`columns` of ``block`` tests each, in order (blocks of
        ~30000 rows keep the writer's memory to ~25-50 MB)."""
        for s in range(0, self.tests.m, block):
            yield self.columns(slice(s, s + block))

    def frames(self, block: int = 80_000):
        """The whole table as DataFrames of ``block`` tests each, in order."""
        for s in range(0, self.tests.m, block):
            yield self.frame(slice(s, s + block))

    def key(self, rows=slice(None)) -> np.ndarray:
        """(m, 6) ranking of the rows (of the tests ``rows``): |studentized| (-1 if not
        finite), outliers first."""
        key = np.abs(self.t[rows])  # one array, edited in place
        key[~np.isfinite(key)] = -1.0
        key[self.marked(rows)] = np.inf
        key[~self.tests.measured[rows]] = -np.inf
        return key

    def worst_tests(self, rows: int, block: int = 1 << 14) -> np.ndarray:
        """Sorted indices of the tests holding the ``rows`` highest-ranked rows (outliers
        first, then largest |studentized|), and of those holding the ``rows`` largest
        |studentized| outliers. The ranking is made a block of tests at a time."""
        top = np.zeros(0, dtype=np.int64)
        for s in range(0, self.tests.m, block):
            key = self.key(slice(s, s + block)).reshape(-1)
            cand = np.concatenate([top, 6 * s + np.arange(key.size)])
            values = np.concatenate([self._flat_key(top), key])
            top = cand[_largest(values, rows)]
        # flat indices of the measured outliers, a block at a time too: the whole (m, 6)
        # |t| and its masks were the analysis's peak memory at 1e6 tests (~60 MB)
        out = np.concatenate([np.zeros(0, dtype=np.int64)] + [
            6 * s + np.flatnonzero((self.marked(slice(s, s + block))
                                    & self.tests.measured[s:s + block]).reshape(-1))
            for s in range(0, self.tests.m, block)])
        t = np.abs(np.nan_to_num(self.t.reshape(-1)[out]))
        top_out = out[_largest(t, rows)]
        return np.unique(np.concatenate([top, top_out]) // 6)

    def _flat_key(self, flat: np.ndarray) -> np.ndarray:
        """The ranking key of the rows at flat indices ``flat`` (test * 6 + component)."""
        i, c = np.divmod(flat, 6)
        key = np.abs(self.t[i, c])
        key[~np.isfinite(key)] = -1.0
        key[self.flags[i, c] | self.beyond(i, c)] = np.inf
        key[~self.tests.measured[i, c]] = -np.inf
        return key

    def histogram(self, block: int = 1 << 16) -> dict:
        """results.json ``residual_histogram`` of every row (counted a block of tests at a
        time: the rows of 1e6 tests are 48 MB)."""
        parts = [histogram(self.t[s:s + block][self.tests.measured[s:s + block]])
                 for s in range(0, self.tests.m, block)]
        out = parts[0]
        out["counts"] = np.sum([h["counts"] for h in parts], axis=0).tolist()
        out["not_finite"] = int(sum(h["not_finite"] for h in parts))
        return out


def _largest(values: np.ndarray, n: int, block: int = 1 << 18) -> np.ndarray:
    """Indices of the ``n`` largest of ``values`` (1-D), ascending, found block by block (an
    index array of every value would be 8 bytes per value). Ties: the lowest indices
    first (of three values +inf at 5, 900 and 7000, n = 2 takes 5 and 900), so the rows
    kept do not depend on the sort's algorithm. NaN is refused where a rank is needed."""
    n = min(n, values.size)
    if n <= 0:
        return np.zeros(0, dtype=np.int64)
    keep = np.zeros(0, dtype=np.int64)
    for s in range(0, values.size, block):
        idx = np.concatenate([keep, np.arange(s, min(s + block, values.size))])
        if idx.size > n:
            v = values[idx]
            if np.isnan(v).any():
                raise ValueError("_largest: a value is NaN (it has no rank)")
            kth = np.partition(v, idx.size - n)[idx.size - n]  # the n-th largest
            above = v > kth
            tied = np.flatnonzero(v == kth)[: n - int(above.sum())]  # idx ascending
            sel = np.flatnonzero(above)
            idx = idx[np.sort(np.concatenate([sel, tied]))]
        keep = idx
    return keep
