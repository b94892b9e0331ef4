"""Number formatting for the report: one function per kind of quantity, units in the header.

SI inside; the report shows joint stiffness in kN m/rad, displacements in
um / urad, angles in degrees, each table header naming its unit.
"""

from __future__ import annotations

import math

MICRO = "\u00b5"
PM = "\u00b1"


def sig(value: float | None, digits: int = 5, zeros: bool = False) -> str:
    """``value`` with ``digits`` significant digits; '-' for None/NaN, 'inf' for infinity.

    ``zeros`` keeps trailing zeros (``2.00`` rather than ``2``).
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    text = f"{value:#.{digits}g}" if zeros else f"{value:.{digits}g}"
    text = text.rstrip(".")
    return text.replace("e+0", "e").replace("e-0", "e-").replace("e+", "e")


def k_kNm(value: float | None) -> str:
    """Joint stiffness (N m/rad) shown in kN m/rad with 5 significant digits."""
    if value is None or not math.isfinite(value):
        return sig(value)
    return sig(value / 1e3, 5, zeros=True)


def interval_kNm(lo: float, hi: float) -> str:
    """A stiffness interval (N m/rad) as ``[lo, hi]`` in kN m/rad."""
    return f"[{k_kNm(lo)}, {k_kNm(hi)}]"


def percent(value: float | None, digits: int = 2) -> str:
    """A ratio as a percentage with ``digits`` decimals and a sign."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{100 * value:+.{digits}f}"


def fixed(value: float | None, decimals: int) -> str:
    """Fixed-point number; '-' for None/NaN."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{value:.{decimals}f}"


def matrix_entry(value: float) -> str:
    """A K_X entry in SI, 3 significant digits in exponent form (e.g. ``1.23e7``)."""
    if value == 0 or not math.isfinite(value):
        return sig(value)
    return f"{value:.2e}".replace("e+0", "e").replace("e-0", "e-").replace("e+", "e")
