"""The columns of the stiffness tests: the public CSV format (deg, N, N m, mm, mrad) and
the tidy SI table's (rad, N, N m, m, rad), the unit factors between them and the
plausible magnitudes (:mod:`analysis.identification.io.measurements`).
"""

from __future__ import annotations

import numpy as np

N_JOINTS = 6
Q_COLS = [f"q{i}_deg" for i in range(1, N_JOINTS + 1)]
W_COLS = ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"]
D_COLS = ["dx_mm", "dy_mm", "dz_mm"]
R_COLS = ["rx_mrad", "ry_mrad", "rz_mrad"]
CSV_COLUMNS = ["pose", *Q_COLS, *W_COLS, *D_COLS, *R_COLS]
#: optional: the wrench of each test's reference reading (its preload), base frame at the
#: tool point (N, N m); the displacement is then loaded minus reference, for w - w_ref.
#: Absent (or empty): an unloaded reference, w_ref = 0. Same names and units in SI.
REF_W_COLS = ["fx_ref_N", "fy_ref_N", "fz_ref_N", "mx_ref_Nm", "my_ref_Nm", "mz_ref_Nm"]

SI_Q = [f"q{i}_rad" for i in range(1, N_JOINTS + 1)]
SI_W = W_COLS
SI_D = ["dx_m", "dy_m", "dz_m", "rx_rad", "ry_rad", "rz_rad"]
SI_COLUMNS = ["pose", *SI_Q, *SI_W, *SI_D]
#: CSV column -> (SI column, factor from CSV unit to SI)
TO_SI = {
    **{c: (s, np.pi / 180.0) for c, s in zip(Q_COLS, SI_Q, strict=True)},
    **{c: (c, 1.0) for c in W_COLS},
    **{c: (s, 1e-3) for c, s in zip(D_COLS + R_COLS, SI_D, strict=True)},
}
COMPONENTS = ["dx", "dy", "dz", "rx", "ry", "rz"]
#: largest magnitude accepted per SI column, far beyond any stiffness test (a typing or
#: unit error otherwise overflows the linear algebra): 10 turns, 10 MN, 10 MN m, 10 m, 1 rad
PLAUSIBLE_MAX = {**{c: 20 * np.pi for c in SI_Q}, **{c: 1e7 for c in SI_W},
                 **{c: 10.0 for c in SI_D[:3]}, **{c: 1.0 for c in SI_D[3:]}}
