"""Numbers as the terminal shows them: vectors and matrices with significant digits.

Shared by the command line's faces and the notes the jobs print as they go.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


def matrix_lines(M: np.ndarray, digits: int = 5) -> list[str]:
    """Rows of ``M`` with ``digits`` significant digits, in columns wide enough for every entry.

    Round-off (below 1e-9 of the largest entry) is shown as 0, never '-0'; a
    matrix whose entries span beyond 1e-3..1e5 is shown in one exponent style.
    """
    import numpy as np

    from analysis.report.formatting import clean, sig

    a = clean(M)
    big = np.abs(a[a != 0])
    if big.size and (big.max() >= 1e5 or big.min() < 1e-3):
        def cell(v):
            return "0" if v == 0 else f"{v:.{digits - 1}e}"
    else:
        def cell(v):
            return sig(v, digits)
    cells = [[cell(v) for v in row] for row in a]
    width = max(len(c) for row in cells for c in row)
    return ["  " + " ".join(f"{c:>{width}}" for c in row) for row in cells]


def vector_text(values, digits: int = 4, zeros: bool = True) -> str:
    """``[a, b, c]`` with ``digits`` significant digits and round-off shown as 0.

    ``zeros`` keeps trailing zeros (``4.000``: a measured-looking value); without,
    ``30`` rather than ``30.000`` (typed inputs: angles, wrench).
    """
    from analysis.report.formatting import clean, eng, sig

    fmt = eng if zeros else sig
    return "[" + ", ".join(fmt(float(v), digits) for v in clean(values)) + "]"
