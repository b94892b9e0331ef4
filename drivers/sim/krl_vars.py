"""KRL system variables of a simulated KUKA KR C4 controller, as KUKAVARPROXY shows them.

Values are KRL text as ``ShowVar`` returns it: structure literals
``{E6AXIS: A1 0.0, ..., E6 0.0}``, ``{E6POS: X .., Y .., Z .., A .., B .., C .., S 6,
T 2, E1 ..}``, ``{FRAME: X .., ..., C ..}`` (mm, deg), enumerations with ``#``
(``#AUT``), integers, ``TRUE``/``FALSE`` and quoted character arrays.

Conventions of the fake (documented in drivers/README.md):

* Cartesian values are in the robot model's base frame with ``$BASE`` = NULLFRAME
  and ``$TOOL`` = the lab's tool; ``A, B, C`` are KUKA's Z-Y'-X'' angles
  (R = Rz(A) Ry(B) Rx(C)).
* ``T`` (turn): bit i set when axis A(i+1) < 0. ``S`` (status): bit 0 the wrist
  centre behind A1 (overhead area), bit 1 A3 >= phi (phi: the A3 angle at which the
  wrist centre lies on the line through A2 and A3, from the model's geometry), bit 2
  A5 <= 0.
"""

from __future__ import annotations

import re

import numpy as np

#: Read-only variables (a write is refused, as the controller does).
READ_ONLY = ("$AXIS_ACT", "$AXIS_ACT_MEAS", "$POS_ACT", "$POS_ACT_MES", "$MODE_OP",
             "$PRO_STATE1", "$VEL_ACT", "$ROB_STOPPED", "$ON_PATH", "$PERI_RDY",
             "$STOPMESS", "$MODEL_NAME[]", "$ROBNAME[]", "$KR_SERIALNO", "$IN")
_INDEXED = re.compile(r"^(\$IN|\$OUT|\$VEL_AXIS|\$ACC_AXIS)\[(\d+)\]$")
_LIMITS = {"$IN": 4096, "$OUT": 4096, "$VEL_AXIS": 6, "$ACC_AXIS": 6}


def real(value: float) -> str:
    """A KRL REAL as text (no exponent, trailing zeros trimmed)."""
    value = 0.0 if abs(value) < 5e-7 else float(value)  # no "-0.0"
    text = f"{value:.6f}".rstrip("0")
    return text + "0" if text.endswith(".") else text


def e6axis(q_deg: np.ndarray) -> str:
    """``{E6AXIS: A1 .., ..., A6 .., E1 0.0, ..., E6 0.0}`` from six angles (deg)."""
    parts = [f"A{i + 1} {real(v)}" for i, v in enumerate(q_deg)]
    parts += [f"E{i} 0.0" for i in range(1, 7)]
    return "{E6AXIS: " + ", ".join(parts) + "}"


def abc_deg(R: np.ndarray) -> np.ndarray:
    """KUKA A, B, C (deg): R = Rz(A) Ry(B) Rx(C)."""
    import warnings

    from scipy.spatial.transform import Rotation

    with warnings.catch_warnings():  # B = +-90 deg: KUKA too reports C = 0 and all in A
        warnings.simplefilter("ignore", UserWarning)
        return Rotation.from_matrix(R).as_euler("ZYX", degrees=True)


def frame(T: np.ndarray) -> str:
    """``{FRAME: X .., Y .., Z .., A .., B .., C ..}`` of a 4x4 transform (m -> mm)."""
    xyz, abc = T[:3, 3] * 1e3, abc_deg(T[:3, :3])
    vals = [*xyz, *abc]
    return "{FRAME: " + ", ".join(f"{k} {real(v)}" for k, v in zip("XYZABC", vals,
                                                                    strict=True)) + "}"


def e6pos(T: np.ndarray, status: int, turn: int) -> str:
    """``{E6POS: X .., ..., C .., S .., T .., E1 0.0, ..}`` of the tool pose (m -> mm)."""
    body = frame(T)[len("{FRAME: "):-1]
    extra = ", ".join(f"E{i} 0.0" for i in range(1, 7))
    return f"{{E6POS: {body}, S {status}, T {turn}, {extra}}}"


def turn_bits(q_ctrl_deg: np.ndarray) -> int:
    """KUKA Turn: bit i set when axis i+1 is negative."""
    return int(sum(1 << i for i, v in enumerate(q_ctrl_deg) if v < 0))


def status_bits(wrist_in_a1: float, a3_deg: float, phi_deg: float, a5_deg: float) -> int:
    """KUKA Status: bit 0 overhead area, bit 1 A3 >= phi, bit 2 A5 <= 0."""
    return int((wrist_in_a1 < 0) | ((a3_deg >= phi_deg) << 1) | ((a5_deg <= 0) << 2))


def indexed(name: str) -> tuple[str, int] | None:
    """``("$OUT", 3)`` for ``$OUT[3]``; None for other names or an index out of range."""
    m = _INDEXED.match(name)
    if not m:
        return None
    base, idx = m.group(1), int(m.group(2))
    return (base, idx) if 1 <= idx <= _LIMITS[base] else None
