"""The tests-data fingerprint of results.json (campaign compare's shared-data check)."""

from __future__ import annotations

import numpy as np

from analysis.identification.io.data_fingerprint import (
    SKETCH_SIZE,
    _rounded,
    fingerprint,
    row_digests,
    shared_rows,
)
from analysis.identification.io.measurements import TestArrays


def _tests(rng, m):
    q = rng.uniform(-3, 3, (m, 6))
    w = rng.normal(size=(m, 6)) * 2000
    d = rng.normal(size=(m, 6)) * 1e-3
    d[::7, 3:] = np.nan  # translational-only rows
    return TestArrays(np.array(["P"] * m, dtype=object), q, w, d, np.isfinite(d),
                      np.arange(m) + 2)


def test_rounding_keeps_thirty_significant_bits():
    def back(v):
        return _rounded(np.array(v, dtype=float)).view(np.float64)

    x = np.array([0.001, np.pi, -2.5e-7, 1234.5678])
    r = back(x)
    assert np.all(np.abs(r - x) <= np.abs(x) * 2.0**-30)  # half the last kept bit
    # ulps apart, the same code; a 1e-8 relative change, another one
    assert np.array_equal(back(np.nextafter(x, np.inf)), r)
    assert np.array_equal(back(np.nextafter(x, -np.inf)), r)
    assert not np.any(back(x * (1 + 1e-8)) == r)
    # a carry into the exponent: 1 - 1e-12 is 1.0; -0.0 is 0.0; every NaN one code
    assert back([1 - 1e-12, -(1 - 1e-12)]).tolist() == [1.0, -1.0]
    assert _rounded(np.array([-0.0]))[0] == _rounded(np.array([0.0]))[0] == 0
    assert _rounded(np.array([np.nan]))[0] == _rounded(np.array([-np.nan]))[0]


def test_same_tests_same_digest_whatever_the_reader_and_order():
    rng = np.random.default_rng(0)
    t = _tests(rng, 50)
    a = fingerprint(t)
    # last-bit differences (two CSV parsers), other pose labels, rows reversed
    ulp = TestArrays(np.array(["Q"] * 50, dtype=object), t.q[::-1] * (1 + 2e-16),
                     t.w[::-1], np.nextafter(t.d[::-1], np.inf), t.measured[::-1], t.line)
    b = fingerprint(ulp)
    assert a["sha256"] == b["sha256"] and a["rows"] == 50
    assert shared_rows(a, b) == 50
    # one displacement changed by 1 um: another campaign's reading
    d = t.d.copy()
    d[3, 0] += 1e-6
    c = fingerprint(TestArrays(t.pose, t.q, t.w, d, t.measured, t.line))
    assert c["sha256"] != a["sha256"] and shared_rows(a, c) == 49
    assert shared_rows(a, fingerprint(_tests(rng, 50))) == 0
    assert len(set(row_digests(t.q, t.w, t.d).tolist())) == 50


def test_the_sketch_of_a_large_campaign_finds_a_shared_share():
    """Beyond SKETCH_SIZE rows the sketch is a uniform sample: B sharing 1500 of A's 5000
    tests (both sketches keep the digests below about 1024/5000 of the range) shows about
    1500 * 1024 / 5000 = 307 of them in both sketches (binomial sd ~ 16)."""
    rng = np.random.default_rng(1)
    a = _tests(rng, 5000)
    b_rows = np.concatenate([np.arange(1500), np.arange(5000, 8500)])
    other = _tests(rng, 3500)
    b = TestArrays(np.array(["P"] * 5000, dtype=object), np.concatenate([a.q[:1500], other.q]),
                   np.concatenate([a.w[:1500], other.w]), np.concatenate([a.d[:1500], other.d]),
                   np.concatenate([a.measured[:1500], other.measured]), b_rows)
    fa, fb = fingerprint(a), fingerprint(b)
    assert len(fa["row_digests"]) == SKETCH_SIZE
    shared = shared_rows(fa, fb)
    assert 240 < shared < 370
