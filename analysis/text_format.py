"""Numbers as text: one function per kind of quantity (significant digits, kN m/rad,
percent, probability levels, UTC time stamps), the unit named by the caller.

Neutral ground: the identification's messages (a refusal's level, an interval's
confidence) and the report's tables format through the same functions, and the
mathematics imports nothing from the report package (:mod:`analysis.report.formatting`
re-exports these for the report). SI inside; the report shows joint stiffness in
kN m/rad, displacements in um / urad, angles in degrees, each table header naming its unit.
"""

from __future__ import annotations

import math

MICRO = "\u00b5"
PM = "\u00b1"
MINUS = "-"
ROUND_OFF = 1e-9  # |value| below this fraction of its table's scale is round-off: shown as 0


def clean(values, scale: float | None = None, rel: float = ROUND_OFF):
    """``values`` with round-off set to exactly 0.

    An entry is round-off when ``|v| <= rel * scale``; ``scale`` defaults to
    the largest finite ``|v|`` (a K_X entry of 4.7e-11 N/m beside 1.6e6 N/m
    is the floating-point residue of a zero, not a stiffness).
    """
    import numpy as np

    a = np.array(values, dtype=float)
    finite = np.isfinite(a)
    if scale is None:
        scale = float(np.max(np.abs(a[finite]), initial=0.0))
    a[finite & (np.abs(a) <= rel * scale)] = 0.0
    return a


def _no_negative_zero(text: str) -> str:
    """'-0', '-0.000' -> '0', '0.000' (a rounded zero has no sign)."""
    if text.startswith("-") and not any(c in "123456789" for c in text.split("e")[0]):
        return text[1:]
    return text


def sig(value: float | None, digits: int = 5, zeros: bool = False) -> str:
    """``value`` with ``digits`` significant digits; '-' for None/NaN, 'inf' for infinity.

    ``zeros`` keeps trailing zeros (``2.00`` rather than ``2``).
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    if value == 0:
        value = 0.0  # drops the sign of -0.0
    text = f"{value:#.{digits}g}" if zeros else f"{value:.{digits}g}"
    text = text.rstrip(".")
    return _no_negative_zero(text.replace("e+0", "e").replace("e-0", "e-").replace("e+", "e"))


def eng(value: float | None, digits: int = 4) -> str:
    """An engineering value with ``digits`` significant digits, without exponent for
    0.001 <= |value| < 10**digits (``1606``, ``162.9``, ``0.9200``), clean zero."""
    if value is None or not math.isfinite(value):
        return sig(value)
    if value == 0:
        return "0"
    mag = abs(value)
    if 1e-3 <= mag < 10 ** digits:
        decimals = max(digits - 1 - math.floor(math.log10(mag)), 0)
        return _no_negative_zero(f"{value:.{decimals}f}")
    return sig(value, digits)


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
    text = f"{100 * value:+.{digits}f}"
    return text if any(c in "123456789" for c in text) else text[1:]


def level(value: float) -> str:
    """A probability as a percentage the way the terminal writes it: a space before the
    sign, at most 4 significant digits ('95 %', '1 %', '99.17 %')."""
    if value is None or not math.isfinite(value):
        return "-"
    return f"{100 * value:.4g} %"


def fixed(value: float | None, decimals: int) -> str:
    """Fixed-point number; '-' for None/NaN."""
    if value is None or not math.isfinite(value):
        return "-"
    return _no_negative_zero(f"{value:.{decimals}f}")


def utc_text(stamp: str | None) -> str:
    """An ISO 8601 UTC time stamp shown to the second: '2026-11-20 09:58:00 UTC' ('-' for
    none; text that is not a time stamp is returned as it is)."""
    from datetime import UTC, datetime

    if not stamp or stamp == "-":
        return "-"
    try:
        t = datetime.fromisoformat(str(stamp).replace("Z", "+00:00"))
    except ValueError:
        return str(stamp)
    if t.tzinfo is not None:
        t = t.astimezone(UTC)
    return t.strftime("%Y-%m-%d %H:%M:%S UTC")
