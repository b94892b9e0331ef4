"""The stiffness tests as arrays (:class:`TestArrays`, SI) and as the tidy SI table.

Public CSV format (one row per test, extra columns ignored, header required)::

    pose, q1_deg..q6_deg,                 joint angles, robot model convention (deg)
    fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm  wrench on the end-effector at the tool point,
                                           base-frame components (N, N m)
    dx_mm, dy_mm, dz_mm                    translation of the tool point, base frame (mm)
    rx_mrad, ry_mrad, rz_mrad              small rotation vector, base frame (mrad);
                                           empty for translational-only measurements
    fx_ref_N .. mz_ref_Nm (optional)       wrench of the reference reading (a preload in
                                           the load's direction), base frame at the tool
                                           point (N, N m); the displacement is then loaded
                                           minus reference and TestArrays.w = w - w_ref.
                                           Absent or all empty: unloaded

Inside the program the same tests are a tidy table in SI units with the columns of
:data:`~analysis.identification.io.columns.SI_COLUMNS` (rad, N, N m, m, rad). Reading a
file: :mod:`analysis.identification.io.csv_reader`; the checks, whose errors name the CSV
line (header = line 1) and the column at fault:
:mod:`analysis.identification.io.table_checks`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.identification.io.columns import REF_W_COLS, SI_D, SI_Q, SI_W, TO_SI
from analysis.identification.io.table_checks import validate_table


@dataclass(frozen=True)
class TestArrays:
    """Tests as arrays (SI). m tests.

    Attributes
    ----------
    pose : (m,) pose labels (str).
    q : (m, 6) joint angles (rad).
    w : (m, 6) wrench [f (N); m (N m)], base frame, at the tool point: the loaded
        reading's minus the reference reading's (``w_ref``) when the references were
        preloaded, what the displacement responds to to first order.
    d : (m, 6) measured displacement screw [dp (m); dr (rad)]; NaN where not measured.
    measured : (m, 6) bool, True where ``d`` holds a measurement.
    line : (m,) CSV line numbers (header = 1) or table row numbers, for messages.
    w_ref : (m, 6) wrench of each test's reference reading [f (N); m (N m)] (a preload),
        base frame at the tool point, or None: every reference reading unloaded. The exact
        model solves the equilibria under w_ref and under w + w_ref.
    """

    __test__ = False  # not a pytest test class

    pose: np.ndarray
    q: np.ndarray
    w: np.ndarray
    d: np.ndarray
    measured: np.ndarray
    line: np.ndarray
    w_ref: np.ndarray | None = None

    @property
    def m(self) -> int:
        return self.q.shape[0]

    def subset(self, rows: np.ndarray) -> TestArrays:
        """The tests at integer or boolean index ``rows``."""
        return TestArrays(
            self.pose[rows], self.q[rows], self.w[rows], self.d[rows],
            self.measured[rows], self.line[rows],
            None if self.w_ref is None else self.w_ref[rows],
        )

    @property
    def has_rotations(self) -> bool:
        return bool(np.any(self.measured[:, 3:]))


def to_arrays(table: pd.DataFrame) -> TestArrays:
    """The tidy SI table as :class:`TestArrays` (validated first)."""
    validate_table(table)
    d = table[SI_D].to_numpy(dtype=float)
    line = table["line"].to_numpy(dtype=int) if "line" in table.columns else np.arange(len(table))
    w = table[SI_W].to_numpy(dtype=float)
    w_ref = None
    if all(c in table.columns for c in REF_W_COLS):
        w_ref = table[REF_W_COLS].to_numpy(dtype=float)
        if np.any(w_ref):
            w = w - w_ref  # the table's wrench is the loaded reading's
        else:
            w_ref = None  # every reference unloaded: the tests of the unloaded format
    return TestArrays(
        pose=table["pose"].astype(str).to_numpy(),
        q=table[SI_Q].to_numpy(dtype=float),
        w=w,
        d=d,
        measured=np.isfinite(d),
        line=line,
        w_ref=w_ref,
    )


def to_csv_frame(table: pd.DataFrame) -> pd.DataFrame:
    """The tidy SI table back in the public CSV units (deg, N, N m, mm, mrad)."""
    out = pd.DataFrame({"pose": table["pose"].to_numpy()})
    for col, (si, factor) in TO_SI.items():
        out[col] = table[si].to_numpy(dtype=float) / factor
    return out


def table_from_arrays(pose, q, w, d) -> pd.DataFrame:
    """Tidy SI table from arrays.

    q (m, 6) rad; w (m, 6) N, N m; d (m, 6) m, rad (NaN = not measured).
    """
    q, w, d = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (q, w, d))
    data = {"pose": np.asarray(pose).astype(str)}
    for j, c in enumerate(SI_Q):
        data[c] = q[:, j]
    for j, c in enumerate(SI_W):
        data[c] = w[:, j]
    for j, c in enumerate(SI_D):
        data[c] = d[:, j]
    return pd.DataFrame(data)
