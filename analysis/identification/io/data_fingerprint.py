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
(m, rad; NaN where not measured) rounded to :data:`MANTISSA_BITS` significant bits
(about 9 decimal digits), so that the same CSV text parsed by two readers (last-bit
differences) gives the same digest, while two independent readings (noise far above
1e-9 relative) never do. (A value within a last bit of a rounding boundary, about 1 in
4e6 values, can still round apart: the sketch then still shows the other rows shared.)
"""

from __future__ import annotations

import hashlib

import numpy as np

#: significant bits kept of each value (30 bits: 9.0 decimal digits)
MANTISSA_BITS = 30
SKETCH_SIZE = 1024
RULE = (f"row digest: 64-bit mix of q (rad), w (N, N m), d (m, rad) rounded to "
        f"{MANTISSA_BITS} significant bits (pose labels and row order ignored); "
        f"sha256 of the sorted row digests; row_digests: the {SKETCH_SIZE} smallest")

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _mix(h: np.ndarray) -> np.ndarray:
    """splitmix64's finaliser, batched (uint64 wraps around)."""
    h = (h ^ (h >> np.uint64(30))) * _M1
    h = (h ^ (h >> np.uint64(27))) * _M2
    return h ^ (h >> np.uint64(31))


def _rounded(values: np.ndarray) -> np.ndarray:
    """uint64 code of each value rounded (half up in magnitude) to MANTISSA_BITS
    significant bits: its IEEE bits with the low bits cleared after adding half of the
    last kept one (a carry moves into the exponent, which renormalises); -0.0 as 0.0 and
    every NaN as one code."""
    v = np.asarray(values, dtype=float) + 0.0  # -0.0 + 0.0 = 0.0
    v = np.where(np.isnan(v), np.nan, v)
    drop = 53 - MANTISSA_BITS  # low bits of the 52-bit fraction dropped
    bits = v.view(np.uint64)
    return (bits + np.uint64(1 << (drop - 1))) & ~np.uint64((1 << drop) - 1)


#: rows digested at a time (bounds the temporary arrays: ~2 MB a block, so the digest adds
#: little more than its own 8 bytes a row to the peak memory of a 1e6-test analysis)
BLOCK_ROWS = 1 << 12


def row_digests(q: np.ndarray, w: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(m,) uint64 digest of each test row (see the module docstring), a block at a time."""
    m = np.shape(q)[0]
    out = np.empty(m, dtype=np.uint64)
    for s in range(0, m, BLOCK_ROWS):
        sl = slice(s, s + BLOCK_ROWS)
        cols = np.concatenate([np.asarray(q[sl], float), np.asarray(w[sl], float),
                               np.asarray(d[sl], float)], axis=1)
        code = _rounded(cols)
        h = np.full(cols.shape[0], np.uint64(0x9E3779B97F4A7C15))
        for c in range(cols.shape[1]):
            h = _mix(h ^ code[:, c])
        out[sl] = h
    return out


def fingerprint(tests) -> dict:
    """results.json ``tests_data`` of :class:`TestArrays` ``tests``."""
    h = row_digests(tests.q, tests.w, tests.d)
    h.sort()  # in place
    digest = hashlib.sha256()  # of the big-endian bytes, a block at a time: no two copies
    for s in range(0, h.size, BLOCK_ROWS):  # of the whole (8 MB each at 1e6 tests)
        digest.update(h[s:s + BLOCK_ROWS].astype(">u8").tobytes())
    return {
        "rows": int(h.size),
        "sha256": digest.hexdigest(),
        "row_digests": [f"{v:016x}" for v in h[:SKETCH_SIZE].tolist()],
        "rule": RULE,
    }


def shared_rows(a: dict, b: dict) -> int:
    """Rows known to be in both campaigns: the digests common to both sketches (every row
    when both campaigns have at most :data:`SKETCH_SIZE`, a lower bound beyond)."""
    return len(set(a["row_digests"]) & set(b["row_digests"]))
