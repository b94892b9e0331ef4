"""Conversion factors from instrument unit names to SI (N, N m, m)."""

from __future__ import annotations

from drivers.errors import ProtocolError

LBF = 4.4482216152605  # N, exact by definition of the pound-force
G0 = 9.80665  # m/s^2, standard gravity

FORCE_TO_N = {
    "n": 1.0, "kn": 1000.0, "lbf": LBF, "klbf": 1000 * LBF, "g": G0 / 1000, "kg": G0,
    "kgf": G0,
}
TORQUE_TO_NM = {
    "nm": 1.0, "n-m": 1.0, "n·m": 1.0, "nmm": 1e-3, "n-mm": 1e-3, "knm": 1000.0, "kn-m": 1000.0,
    "lbf-in": LBF * 0.0254, "lbfin": LBF * 0.0254, "lbf-ft": LBF * 0.3048, "lbfft": LBF * 0.3048,
    "g-cm": G0 / 1000 * 0.01, "kg-cm": G0 * 0.01, "kgf-cm": G0 * 0.01,
}
LENGTH_TO_M = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "in": 0.0254, "ft": 0.3048}


def _lookup(table: dict[str, float], name: str, what: str) -> float:
    key = name.strip().lower().replace(" ", "")
    if key not in table:
        raise ProtocolError(f"unknown {what} unit {name!r} (known: {', '.join(sorted(table))})")
    return table[key]


def force_factor(name: str) -> float:
    """Newtons per instrument force unit ``name`` (e.g. ``"lbf"``)."""
    return _lookup(FORCE_TO_N, name, "force")


def torque_factor(name: str) -> float:
    """Newton-metres per instrument torque unit ``name`` (e.g. ``"N-mm"``)."""
    return _lookup(TORQUE_TO_NM, name, "torque")


def length_factor(name: str) -> float:
    """Metres per instrument length unit ``name`` (e.g. ``"mm"``)."""
    return _lookup(LENGTH_TO_M, name, "length")
