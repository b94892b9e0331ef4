"""Text pieces the MJCF, URDF and SDF writers share: numbers, rotations, comments.

Numbers are written with ``repr`` (the shortest text that reads back as the same double),
so a description read back gives the model's kinematics to rounding; entries below
:data:`SNAP` (cos 90 deg = 6e-17 in a DH table) are written as 0.
"""

from __future__ import annotations

import textwrap
from xml.sax.saxutils import quoteattr

import numpy as np
import pinocchio as pin

#: |x| below this is written as 0 (m, rad or unitless): far below any length or angle a
#: simulator resolves
SNAP = 1e-15


def num(x: float) -> str:
    """One number, exact to the double (``repr``), tiny values and -0.0 as ``0``."""
    x = float(x)
    if abs(x) < SNAP:
        return "0"
    text = repr(x)
    return text[:-2] if text.endswith(".0") else text


def nums(values) -> str:
    """Numbers separated by spaces."""
    return " ".join(num(v) for v in np.ravel(values))


def attr(value: str) -> str:
    """An XML attribute value with its quotes (escaped)."""
    return quoteattr(str(value))


def rpy(rot: np.ndarray) -> np.ndarray:
    """Fixed-axis roll, pitch, yaw (rad) of a rotation matrix: R = Rz(yaw) Ry(pitch) Rx(roll),
    the URDF and SDF convention."""
    return np.asarray(pin.rpy.matrixToRpy(np.asarray(rot, dtype=float)), dtype=float)


def quat_wxyz(rot: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix, w >= 0 (MJCF's ``quat``)."""
    q = pin.Quaternion(np.asarray(rot, dtype=float))
    q.normalize()
    out = np.array([q.w, q.x, q.y, q.z], dtype=float)
    return -out if out[0] < 0 else out


#: comment lines are wrapped at this many columns (words are never split)
COMMENT_WIDTH = 92


def comment(lines, indent: str = "") -> str:
    """An XML comment of ``lines``, wrapped at :data:`COMMENT_WIDTH`; ``--`` (not allowed in a
    comment) becomes ``- -``."""
    body = []
    for line in lines:
        for part in str(line).splitlines() or [""]:
            while "--" in part:
                part = part.replace("--", "- -")
            hang = "  " if part.startswith("- ") else ""
            body += textwrap.wrap(part, COMMENT_WIDTH, initial_indent=f"{indent}  ",
                                  subsequent_indent=f"{indent}  {hang}",
                                  break_long_words=False, break_on_hyphens=False) or [""]
    return "\n".join([f"{indent}<!--", *body, f"{indent}-->"])


def left_out_lines(model) -> list[str]:
    """The comment lines naming what the robot model has and this file does not carry, then
    the notes (placeholders, K_C) of a :class:`~analysis.export.sim_model.SimModel`."""
    lines = []
    if model.left_out:
        lines += ["Not carried by this file (the robot model has them):",
                  *[f"- {item}" for item in model.left_out]]
    if model.notes:
        lines += ["Notes:", *[f"- {item}" for item in model.notes]]
    return lines
