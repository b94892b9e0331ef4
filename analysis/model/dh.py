"""Denavit-Hartenberg parameter tables turned into Pinocchio models.

Two conventions are supported, both with revolute joints about the local z axis:

* ``standard_dh`` (Denavit-Hartenberg as in Spong, Craig's "distal" form):
  ``T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``.
* ``modified_dh`` (Khalil-Kleinfinger, used by Dumas et al. 2011, Table 1):
  ``T_j = Rx(alpha_j) Tx(d_j) Rz(theta_j) Tz(r_j)``.

``theta_i = q_i + theta0_i`` where ``q`` is the model's joint variable. All
lengths in metres, angles in radians.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from analysis.choices import GEOMETRY_CONVENTIONS


@dataclass(frozen=True)
class DHRow:
    """One joint of a DH table (SI units).

    For ``standard_dh``: ``a`` (m), ``alpha`` (rad), ``d`` (m), ``theta0`` (rad).
    For ``modified_dh``: ``alpha`` (rad), ``d`` (m, along x_{j-1}), ``r`` (m, along z_j),
    ``theta0`` (rad). Unused fields are zero.
    """

    alpha: float = 0.0
    a: float = 0.0
    d: float = 0.0
    r: float = 0.0
    theta0: float = 0.0


def _rx(angle: float) -> np.ndarray:
    return pin.utils.rotate("x", angle)


def _rz(angle: float) -> np.ndarray:
    return pin.utils.rotate("z", angle)


def _se3(rot: np.ndarray, trans: np.ndarray) -> pin.SE3:
    return pin.SE3(np.asarray(rot, dtype=float), np.asarray(trans, dtype=float))


def standard_fixed(row: DHRow) -> pin.SE3:
    """Fixed part ``Rz(theta0) Tz(d) Tx(a) Rx(alpha)`` of a standard-DH link."""
    return (
        _se3(_rz(row.theta0), np.zeros(3))
        * _se3(np.eye(3), [0.0, 0.0, row.d])
        * _se3(np.eye(3), [row.a, 0.0, 0.0])
        * _se3(_rx(row.alpha), np.zeros(3))
    )


def modified_fixed(row: DHRow) -> pin.SE3:
    """Fixed part ``Rx(alpha) Tx(d) Rz(theta0) Tz(r)`` of a modified-DH link."""
    return (
        _se3(_rx(row.alpha), np.zeros(3))
        * _se3(np.eye(3), [row.d, 0.0, 0.0])
        * _se3(_rz(row.theta0), np.zeros(3))
        * _se3(np.eye(3), [0.0, 0.0, row.r])
    )


def build_dh_model(
    rows: list[DHRow],
    convention: str,
    tool: pin.SE3 | None = None,
    lower: np.ndarray | None = None,
    upper: np.ndarray | None = None,
    name: str = "robot",
) -> tuple[pin.Model, int]:
    """Build a Pinocchio model of a serial revolute chain from a DH table.

    Parameters
    ----------
    rows : one :class:`DHRow` per joint, base to tip.
    convention : ``"standard_dh"`` or ``"modified_dh"``.
    tool : transform flange -> tool point P (m); identity when ``None``.
    lower, upper : joint limits (rad), in the model's joint variable.

    Returns
    -------
    (model, tip_frame_id) : the tip frame is P, named ``"tool"``; a frame
    ``"flange"`` is added too.
    """
    if convention not in GEOMETRY_CONVENTIONS:
        raise ValueError(f"unknown DH convention {convention!r}")
    model = pin.Model()
    model.name = name
    parent = 0
    n = len(rows)
    for i, row in enumerate(rows):
        if convention == "modified_dh":
            placement = modified_fixed(row)
        else:
            placement = pin.SE3.Identity() if i == 0 else standard_fixed(rows[i - 1])
        parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
        # Links are massless here: the stiffness model neglects gravity and inertia.
        model.appendBodyToJoint(parent, pin.Inertia.Zero(), pin.SE3.Identity())
    flange = pin.SE3.Identity() if convention == "modified_dh" else standard_fixed(rows[-1])
    lo = np.full(n, -np.pi * 2) if lower is None else np.asarray(lower, dtype=float)
    hi = np.full(n, np.pi * 2) if upper is None else np.asarray(upper, dtype=float)
    model.lowerPositionLimit = lo
    model.upperPositionLimit = hi
    flange_id = model.addFrame(
        pin.Frame("flange", parent, flange, pin.FrameType.OP_FRAME)
    )
    tool = pin.SE3.Identity() if tool is None else tool
    tip_id = model.addFrame(pin.Frame("tool", parent, flange * tool, pin.FrameType.OP_FRAME))
    del flange_id
    return model, tip_id
