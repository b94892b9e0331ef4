"""Large results are summarised: results.json and the report list the worst residuals."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.identification.io.results_json import residual_summary


def _residuals(n_tests: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    t = rng.normal(size=n_tests * 3)
    t[7] = np.nan
    return pd.DataFrame({
        "test": np.repeat(np.arange(n_tests), 3), "line": np.repeat(np.arange(n_tests), 3) + 2,
        "pose": pd.Categorical(np.repeat([f"P{i}" for i in range(n_tests)], 3)),
        "component": pd.Categorical(np.tile(["dx", "dy", "dz"], n_tests)),
        "residual": t * 1e-5, "studentized": t, "outlier": np.arange(n_tests * 3) == 11,
    })


def test_all_rows_listed_up_to_the_limit():
    res = _residuals(10)
    out = residual_summary(res, listed=30)
    assert out["residuals_listed"] == "all 30 rows"
    assert [r["test"] for r in out["residuals"]] == list(res["test"])
    assert sum(out["residual_histogram"]["counts"]) == 29
    assert out["residual_histogram"]["not_finite"] == 1


def test_beyond_the_limit_the_largest_studentized_outliers_first():
    res = _residuals(400, seed=1)
    out = residual_summary(res, listed=25)
    listed = pd.DataFrame(out["residuals"])
    assert len(listed) == 25 and "25 of 1200 rows" in out["residuals_listed"]
    assert listed["outlier"].iloc[0]  # the outlier first, whatever its |t|
    rest = np.abs(listed["studentized"].iloc[1:].to_numpy())
    assert np.all(np.diff(rest) <= 0)
    finite = np.abs(res["studentized"][~res["outlier"]].dropna())
    assert rest.min() >= np.sort(finite.to_numpy())[-24]  # the 24 largest non-outliers
    counts = out["residual_histogram"]["counts"]
    assert sum(counts) == 1199
    edges = out["residual_histogram"]["studentized_edges"]
    assert edges[0] is None and edges[-1] is None and len(counts) == len(edges) - 1


def test_report_table_lists_the_worst_tests(monkeypatch):
    from types import SimpleNamespace

    from analysis.report import build

    res = _residuals(50, seed=2)
    worst_test = int(res.loc[res["studentized"].abs().idxmax(), "test"])
    result = SimpleNamespace(residuals=res, outlier_threshold=3.5, robust=None,
                             residual_rows=None)
    monkeypatch.setattr(build, "REPORT_TESTS_LISTED", 2)
    table = build.residual_table(result)
    listed = sorted(int(r[0]) - 1 for r in table.rows)
    assert listed == sorted({3, worst_test})  # the outlier's test (row 11) and the worst
    assert "the 2 of 50 tests" in table.caption
    monkeypatch.setattr(build, "REPORT_TESTS_LISTED", 200)
    assert len(build.residual_table(result).rows) == 50


def _lowest_index_first(values, n):
    """The n largest by a stable sort on (-value, index): ties, lowest index first."""
    return np.sort(np.lexsort((np.arange(values.size), -values))[:n])


def test_largest_by_blocks_equals_a_full_sort():
    from analysis.identification.io.residual_rows import _largest

    rng = np.random.default_rng(3)
    values = rng.normal(size=10_007)
    values[[5, 900, 7000]] = np.inf  # outliers rank first
    values[[11, 3000, 9999]] = -np.inf  # not measured: last
    values[[20, 2000, 5000, 8000]] = values[40]  # a finite tie
    for n in (0, 1, 2, 3, 50, 10_004, 10_005, 10_007, 20_000):
        for block in (997, 10, 1 << 18):
            got = _largest(values, n, block=block)
            np.testing.assert_array_equal(got, _lowest_index_first(values, n))


def test_largest_breaks_ties_by_the_lowest_index():
    from analysis.identification.io.residual_rows import _largest

    values = np.zeros(10_007)
    values[[5, 900, 7000]] = np.inf
    np.testing.assert_array_equal(_largest(values, 2, block=997), [5, 900])
    np.testing.assert_array_equal(_largest(values, 3, block=997), [5, 900, 7000])
    np.testing.assert_array_equal(_largest(values, 5, block=997), [0, 1, 5, 900, 7000])
    values[[2, 9000]] = -np.inf
    np.testing.assert_array_equal(_largest(values, 10_006, block=997),
                                  np.setdiff1d(np.arange(10_007), [9000]))
    values[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        _largest(values, 4, block=997)


def test_worst_tests_by_blocks_equal_one_block():
    from analysis.identification.io.measurements import TestArrays
    from analysis.identification.io.residual_rows import ResidualRows

    rng = np.random.default_rng(5)
    m = 500
    measured = rng.random((m, 6)) > 0.1
    flags = np.zeros((m, 6), bool)
    flags[[3, 77, 401], [0, 4, 2]] = True
    measured |= flags
    t = np.where(measured, rng.normal(size=(m, 6)), np.nan)
    tests = TestArrays(pose=np.array([f"P{i // 5}" for i in range(m)], dtype=object),
                       q=np.zeros((m, 6)), w=np.ones((m, 6)), d=np.zeros((m, 6)),
                       measured=measured, line=np.arange(m) + 2)
    rows = ResidualRows(tests, np.zeros((m, 6)), np.ones((m, 6)), t, flags)
    for n in (3, 10, 100, 3000):  # at least the three outliers (tied at the top)
        whole = rows.worst_tests(n, block=10**6)
        np.testing.assert_array_equal(rows.worst_tests(n, block=7), whole)
        key = rows.key().reshape(-1)
        want = np.argsort(key)[::-1][:n] // 6
        assert set(want) <= set(whole) and {3, 77, 401} <= set(whole)
    assert rows.histogram(block=7) == rows.histogram(block=10**6)
    assert sum(rows.histogram()["counts"]) + rows.histogram()["not_finite"] == measured.sum()
