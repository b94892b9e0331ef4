"""The axis-2 gravity compensator's stated law: joint 2's compliance per pose.

A model file written by ``campaign analyze --model compensator`` (or ``auto`` choosing a
class with the compensator) carries in ``[model_class]``
``compensator = {c1 = ..., c2 = ..., q2ref_rad = ...}``: joint 2's compliance follows
its angle,

    x2(q2) = x2 + c1 t + c2 t^2,   t = q2 - q2ref,

x = 1/k (rad/(N m)), q2 (rad, model convention), x2 = 1/k2 the file's joint-2 compliance
(the class fit identified it at q2ref), c1 in rad/(N m) per rad, c2 per rad^2. THE one
place every command takes it from (``campaign stiffness``, ``campaign maps``, the
predicted deflection and ``campaign compensate``, so the GUI's Use view): the law is
evaluated at the commanded (unloaded) joints, as the class fit's columns were.

The stiffness is written k2(q2) = k2 / (1 + k2 (c1 t + c2 t^2)), the same number as
1/x2(q2) up to rounding, so that k2(q2ref) is the file's k2 exactly. A model file
without the law: :func:`pose_stiffness` returns the k it was given (the same array), so
the joint-only path runs no new arithmetic. Where the law leaves its range
(x2(q2) <= 0) the pose is refused rather than given a negative stiffness.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError

#: the joint (0-based) the compensator law is for: axis 2
COMP_JOINT = 1


class LawRangeError(InputError):
    """The compensator law leaves its range (x2(q2) <= 0) at some poses: ``bad`` (...,)
    masks them (for a caller that names them otherwise, e.g. by CSV line)."""

    def __init__(self, message: str, *, where: str, bad: np.ndarray) -> None:
        super().__init__(message, where=where)
        self.message = message
        self.bad = bad


@dataclass(frozen=True)
class CompensatorLaw:
    """x2(q2) = 1/k2 + c1 (q2 - q2ref) + c2 (q2 - q2ref)^2 of a model file.

    c1: rad/(N m) per rad; c2: rad/(N m) per rad^2; q2ref: rad (model convention);
    source: the model file (for messages)."""

    c1: float
    c2: float
    q2ref: float
    source: str

    def text(self) -> str:
        """One line saying the law, SI."""
        return (f"axis-2 compensator law of {self.source}: x2(q2) = 1/k2 + c1 t + c2 t^2, "
                f"t = q2 - {self.q2ref:.6g} rad, c1 = {self.c1:.6g} rad/(N m) per rad, "
                f"c2 = {self.c2:.6g} rad/(N m) per rad^2, evaluated at the commanded q2")


def compensator_law_of(robot) -> CompensatorLaw | None:
    """The compensator law of a robot's model file (``[model_class] compensator`` with c1,
    c2 and q2ref_rad), or None (no law: joint springs as given). A compensator of known
    geometry (preload, rate) without c1, c2 is not a law of x2 and gives None."""
    mc = getattr(robot, "model_class", None) or {}
    comp = mc.get("compensator") or {}
    if "c1" not in comp and "c2" not in comp:
        return None
    if "q2ref_rad" not in comp:
        raise InputError("the compensator law has c1, c2 but no q2ref_rad",
                         where=f"{_source(robot)} [model_class] compensator")
    return CompensatorLaw(float(comp.get("c1", 0.0)), float(comp.get("c2", 0.0)),
                          float(comp["q2ref_rad"]), _source(robot))


def _source(robot) -> str:
    return str(getattr(robot, "source_file", None) or getattr(robot, "name", "model file"))


def pose_stiffness(robot, q: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The joint stiffness per pose (..., n) (N m/rad) at joint angles q (..., n) (rad)
    from the file's (or the given) k (n,): joint 2 at k2 / (1 + k2 (c1 t + c2 t^2)),
    t = q2 - q2ref, where the model file carries the compensator law; k itself (the
    same array, (n,)) where it does not.

    Raises :class:`LawRangeError` (an :class:`~analysis.errors.InputError`) naming the
    model file and the first pose where x2(q2) <= 0 (the law has left its range)."""
    law = compensator_law_of(robot)
    if law is None:
        return k
    q = np.asarray(q, dtype=float)
    k = np.asarray(k, dtype=float)
    t = q[..., COMP_JOINT] - law.q2ref
    # 1 + k2 dx2 = k2 x2(q2): exactly 1 at q2ref, so k2(q2ref) is the file's k2 exactly
    rel = 1.0 + k[COMP_JOINT] * (law.c1 * t + law.c2 * t * t)
    bad = ~(rel > 0.0)
    if np.any(bad):
        i = np.unravel_index(int(np.flatnonzero(bad)[0]), bad.shape) if bad.ndim else ()
        at = f"pose {tuple(int(v) for v in i)} " if bad.ndim else ""
        raise LawRangeError(
            f"the axis-2 compensator law leaves its range at {at}q2 = "
            f"{np.degrees(q[(*i, COMP_JOINT)]):.4f} deg: x2(q2) = 1/k2 + c1 t + c2 t^2 = "
            f"{rel[i] / k[COMP_JOINT]:.4g} rad/(N m) <= 0 (t = {t[i]:.4g} rad from q2ref "
            f"= {np.degrees(law.q2ref):.4f} deg); no stiffness is predicted there",
            where=f"{law.source} [model_class] compensator", bad=bad)
    out = np.broadcast_to(k, q.shape).copy()
    out[..., COMP_JOINT] = k[COMP_JOINT] / rel
    return out


def law_covariance_of(robot) -> tuple[tuple[str, ...], np.ndarray, np.ndarray,
                                       np.ndarray | None] | None:
    """(names ``c1``/``c2`` of the law's identified parameters, their covariance (m, m),
    their cross-covariance with x = 1/k (n, m), with the link entries of
    ``[model_class.link_covariance]`` (L, m) or None) from a model file's
    ``[model_class.compensator_covariance]`` (SI), or None (no law, or a file written
    before the law's covariance was kept: c1, c2 then count as exact)."""
    if compensator_law_of(robot) is None:
        return None
    mc = getattr(robot, "model_class", None) or {}
    cc = mc.get("compensator_covariance")
    if not cc or not cc.get("parameters"):
        return None
    link = cc.get("link_cross")
    return (tuple(cc["parameters"]), np.asarray(cc["matrix"], dtype=float),
            np.asarray(cc["joint_cross"], dtype=float),
            np.asarray(link, dtype=float) if link else None)


def _gradient(robot, q: np.ndarray, names) -> np.ndarray:
    """d x2(q2) / d(c1, c2) (..., m): t and t^2, t = q2 - q2ref (rad), per named
    parameter."""
    t = np.asarray(q, dtype=float)[..., COMP_JOINT] - compensator_law_of(robot).q2ref
    return np.stack([t if n == "c1" else t * t for n in names], axis=-1)


def pose_compliance_covariance(robot, q: np.ndarray, cov_x: np.ndarray) -> np.ndarray:
    """The covariance (..., n, n) ((rad/(N m))^2) of the joint compliances at joint angles
    q (..., n) (rad), x(q) = x + e2 (c1 t + c2 t^2), from that of x = 1/k (n, n) and the
    law's ``[model_class.compensator_covariance]``: cov_x + e2 u^T + u e2^T + e2 e2^T
    g^T C_cc g, u = C_xc g, g = (t, t^2). cov_x itself (the same array) when the model
    file has no law or no covariance for it (c1, c2 exact: dx2(q2)/dx2 = 1)."""
    lc = law_covariance_of(robot)
    if lc is None:
        return cov_x
    names, C_cc, C_xc, _ = lc
    g = _gradient(robot, q, names)
    u = g @ C_xc.T  # (..., n): cov(x, c1 t + c2 t^2)
    var = np.einsum("...a,ab,...b->...", g, C_cc, g)
    out = np.array(np.broadcast_to(cov_x, (*g.shape[:-1], *np.shape(cov_x))), dtype=float)
    out[..., COMP_JOINT, :] += u
    out[..., :, COMP_JOINT] += u
    out[..., COMP_JOINT, COMP_JOINT] += var
    return out


def pose_link_cross(robot, q: np.ndarray, C_xl: np.ndarray) -> np.ndarray:
    """The cross-covariance (..., n, L) of the joint compliances at q (..., n) (rad) with
    the model file's link entries: C_xl (n, L) plus, in joint 2's row, (C_lc g)^T
    (the law's link_cross, g = (t, t^2)); C_xl itself when the file has none of it."""
    lc = law_covariance_of(robot)
    if lc is None or lc[3] is None:
        return C_xl
    names, _, _, C_lc = lc
    g = _gradient(robot, q, names)
    out = np.array(np.broadcast_to(C_xl, (*g.shape[:-1], *C_xl.shape)), dtype=float)
    out[..., COMP_JOINT, :] += g @ C_lc.T
    return out


def law_uncertainty_text(robot) -> str:
    """What the intervals of a model file with the compensator law include of it ("" without
    the law), said wherever an interval is computed from the joint covariance."""
    if compensator_law_of(robot) is None:
        return ""
    if law_covariance_of(robot) is not None:
        return ("the axis-2 compensator law's c1, c2 covariance and cross-covariance (model "
                "file [model_class.compensator_covariance]) propagated into x2(q2)'s")
    return LAW_UNCERTAINTY_TEXT


#: said wherever an interval is computed with the law: what it does not include
LAW_UNCERTAINTY_TEXT = ("the axis-2 compensator law's c1, c2 are taken as exact (the model "
                        "file has no covariance for them): the intervals propagate the "
                        "joint compliances' covariance only, x2's at q2ref moved to the "
                        "pose's q2")
