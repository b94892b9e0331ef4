"""A fingerprint of the tests an identification used, so that two campaigns sharing data show.

``campaign compare`` treats A and B as independent measurements; a copy of the same run,
or the run's ``tests.csv`` imported again with ``--measurements``, would be compared as if
independent (z = 0, a false "no evidence of change"). results.json therefore records
``tests_data``:

* ``sha256``: SHA-256 of the sorted 64-bit digests of every test row (so the order of the
  rows and the pose labels do not matter);
* ``row_digests``: the :data:`SKETCH_SIZE` smallest row digests (hex), every row of a
  campaign up to that size, a uniform sample (bottom-k sketch) beyond: two campaigns
  sharing a fraction f of their rows share about f * SKETCH_SIZE of these;
* ``rows`` and the ``rule``.

A row digest hashes the joint angles q (rad), wrench w (N, N m) and displacement d
(m, rad; NaN where not measured) rounded to :data:`SIGNIFICANT_DIGITS` significant
digits, so that the same CSV text parsed by two readers (last-bit differences) gives the
same digest, while two independent readings (noise far above 1e-9 relative) never do.
"""

from __future__ import annotations

import hashlib

import numpy as np

SIGNIFICANT_DIGITS = 9
SKETCH_SIZE = 1024
RULE = (f"row digest: 64-bit mix of q (rad), w (N, N m), d (m, rad) rounded to "
        f"{SIGNIFICANT_DIGITS} significant digits (pose labels and row order ignored); "
        f"sha256 of the sorted row digests; row_digests: the {SKETCH_SIZE} smallest")

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_NAN_MANTISSA = np.int64(-(2**62))


def _mix(h: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser, batched (uint64 wraps around)."""
    h = (h ^ (h >> np.uint64(30))) * _M1
    h = (h ^ (h >> np.uint64(27))) * _M2
    return h ^ (h >> np.uint64(31))


def _rounded(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(mantissa, exponent) int64 of ``values`` at SIGNIFICANT_DIGITS digits; 0 -> (0, 0)."""
    v = np.asarray(values, dtype=float)
    finite = np.isfinite(v) & (v != 0)
    a = np.where(finite, np.abs(v), 1.0)
    e = np.floor(np.log10(a)).astype(np.int64) - (SIGNIFICANT_DIGITS - 1)
    mant = np.rint(np.where(finite, v, 0.0) / 10.0 ** e.astype(float)).astype(np.int64)
    big = np.abs(mant) >= 10 ** SIGNIFICANT_DIGITS  # 9.9999999996e8 rounded up: renormalise
    mant = np.where(big, mant // 10, mant)
    e = np.where(big, e + 1, e)
    small = finite & (np.abs(mant) < 10 ** (SIGNIFICANT_DIGITS - 1))
    mant = np.where(small, mant * 10, mant)
    e = np.where(small, e - 1, e)
    mant = np.where(np.isnan(v), _NAN_MANTISSA, mant)
    e = np.where(finite, e, 0)
    return mant, e


def row_digests(q: np.ndarray, w: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(m,) uint64 digest of each test row (see the module docstring)."""
    cols = np.concatenate([np.asarray(q, float), np.asarray(w, float),
                           np.asarray(d, float)], axis=1)
    mant, e = _rounded(cols)
    h = np.full(cols.shape[0], np.uint64(0x9E3779B97F4A7C15))
    with np.errstate(over="ignore"):
        for c in range(cols.shape[1]):
            h = _mix(h ^ mant[:, c].astype(np.uint64))
            h = _mix(h ^ (e[:, c].astype(np.uint64) + np.uint64(c << 16)))
    return h


def fingerprint(tests) -> dict:
    """results.json ``tests_data`` of :class:`TestArrays` ``tests``."""
    h = np.sort(row_digests(tests.q, tests.w, tests.d))
    return {
        "rows": int(h.size),
        "sha256": hashlib.sha256(h.astype(">u8").tobytes()).hexdigest(),
        "row_digests": [f"{v:016x}" for v in h[:SKETCH_SIZE].tolist()],
        "rule": RULE,
    }


def shared_rows(a: dict, b: dict) -> int:
    """Rows known to be in both campaigns: the digests common to both sketches (every row
    when both campaigns have at most :data:`SKETCH_SIZE`, a lower bound beyond)."""
    return len(set(a["row_digests"]) & set(b["row_digests"]))
