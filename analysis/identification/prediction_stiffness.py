"""The identified joint stiffness completed for prediction: a joint not identified takes
the model's nominal stiffness when it has one, else is taken as rigid.

Used by the exported model (``model.toml``) and the report's predictions at the tool.
"""

from __future__ import annotations

import numpy as np

RIGID = 1e12  # N m/rad: a joint taken as rigid


def stiffness_for_prediction(
    k: np.ndarray, nominal: np.ndarray | None
) -> tuple[np.ndarray, list[str]]:
    """Identified k (6,) (N m/rad) completed for prediction, and a note per completed joint."""
    out = np.asarray(k, dtype=float).copy()
    notes = []
    for j in np.flatnonzero(~np.isfinite(out)):
        if nominal is not None and np.isfinite(nominal[j]):
            out[j] = nominal[j]
            notes.append(f"k{j + 1} not identified: the model's nominal value is used")
        else:
            out[j] = RIGID
            notes.append(f"k{j + 1} not identified: joint {j + 1} taken as rigid")
    return out, notes
