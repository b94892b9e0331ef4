"""The block CSV writer: the bytes of pandas' to_csv, whatever the values."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.identification.io.table_csv import float_text, write_frame


def _awkward_floats(rng, n: int) -> np.ndarray:
    """Floats of every layout: each decade from 1e-320 to 1e308, the powers of ten and
    their neighbours, integers, signed zeros, NaN, inf, subnormals, random bit patterns."""
    powers = 10.0 ** np.arange(-20, 24)
    special = np.concatenate([
        powers, -powers, np.nextafter(powers, 0), np.nextafter(powers, np.inf),
        [0.0, -0.0, np.nan, np.inf, -np.inf, 5e-324, -5e-324, 2.2250738585072014e-308,
         1.7976931348623157e308, 1.0, -1.0, 2e-05, -3e-06, 7e-07, 123456.0, 1e15, 1e10,
         -9999999999.0, 12345678901234.0, 0.1, 1 / 3, 1e-05, 9.999999999999999e-05],
    ])
    decades = rng.normal(size=n) * 10.0 ** rng.integers(-320, 308, n)
    small = rng.normal(size=n) * 10.0 ** rng.integers(-11, 17, n)  # the layouts' borders
    bits = rng.integers(0, 2**64 - 1, n, dtype=np.uint64).view(np.float64)
    rounded = np.round(rng.normal(size=n) * 1e6) / 10.0 ** rng.integers(0, 9, n)
    out = np.concatenate([special, decades, small, bits, rounded, np.trunc(small)])
    return out[rng.permutation(out.size)]


def test_float_text_is_numpy_repr():
    """float_text gives str(np.float64) of every value (NaN as null): what pandas writes."""
    rng = np.random.default_rng(11)
    x = _awkward_floats(rng, 60_000)
    got = np.asarray(float_text(x).to_pylist(), dtype=object)
    want = x.astype(str).astype(object)
    want[np.isnan(x)] = None
    bad = np.flatnonzero(got != want)
    assert bad.size == 0, [(x[i], got[i], want[i]) for i in bad[:5]]


@pytest.mark.parametrize("block", [700, 100_000])
def test_write_frame_bytes_equal_pandas(tmp_path, block):
    """write_frame's file is byte for byte frame.to_csv(index=False): floats of every
    layout, NaN, signed zeros, integers, booleans, categoricals, text that needs quotes
    (comma, quote, line break), missing text, pandas' str dtype."""
    rng = np.random.default_rng(5)
    n = 4000
    x = _awkward_floats(rng, n)[:n]
    labels = ["P1", "P,2", 'say "3"', "P\n4", "Pö5", " P6 ", ""]
    text = np.array([labels[i] for i in rng.integers(0, len(labels), n)], dtype=object)
    text[rng.random(n) < 0.05] = None
    text[rng.random(n) < 0.05] = np.nan
    frame = pd.DataFrame({
        "test": np.arange(n, dtype=np.int64) - 7,
        "line": rng.integers(0, 2**31, n).astype(np.int32),
        "pose": pd.Categorical.from_codes(rng.integers(-1, 4, n), categories=labels[:4]),
        "component": pd.Categorical.from_codes(rng.integers(0, 6, n),
                                               categories=["dx", "dy", "dz", "rx", "ry", "rz"]),
        "measured": x,
        "residual": rng.normal(size=n) * 10.0 ** rng.integers(-9, -3, n),
        "sigma": np.where(rng.random(n) < 0.5, 2e-05, 1e-06 * rng.integers(1, 30, n)),
        "studentized": np.where(rng.random(n) < 0.1, np.nan, rng.normal(size=n)),
        "outlier": rng.random(n) < 0.3,
        "note": text,
        "held_out_pose": pd.array([f"P{i}" for i in range(n)], dtype="str"),
        "weight": np.where(rng.random(n) < 0.5, 1.0, rng.random(n)),
    })
    path = tmp_path / "new.csv"
    write_frame(frame, path, block=block)
    want = frame.to_csv(index=False).encode()
    assert path.read_bytes() == want
    # the quoted-cell path and the plain path both ran: blocks without any text to quote
    plain = frame.drop(columns=["note"])
    plain["pose"] = plain["pose"].cat.remove_categories(["P,2", 'say "3"', "P\n4"])
    write_frame(plain, path, block=block)
    assert path.read_bytes() == plain.to_csv(index=False).encode()


def test_write_frame_falls_back_to_pandas_for_other_columns(tmp_path):
    """Columns the writer does not take (float32, mixed objects, dates) still give
    pandas' bytes."""
    frame = pd.DataFrame({
        "a": np.array([1.5, np.nan, 1e-7], dtype=np.float32),
        "b": [1, "x", 2.5],
        "c": pd.to_datetime(["2024-01-01", "2024-01-02", None]),
        "d": [0.1, 0.2, 0.3],
    })
    path = tmp_path / "t.csv"
    write_frame(frame, path, block=2)
    assert path.read_bytes() == frame.to_csv(index=False).encode()
    one = pd.DataFrame({"x": ["", "a"]})
    write_frame(one, path)
    assert path.read_bytes() == one.to_csv(index=False).encode()
    empty = frame.iloc[:0]
    write_frame(empty, path)
    assert path.read_bytes() == empty.to_csv(index=False).encode()
