"""Which gears change flank in each planned test, from the robot file's gravity model.

A gear with lost motion rests on the flank of the torque it carries, J^T w - g(q)
(:func:`analysis.model.gravity.gear_torques`). Between a test's reference reading
(wrench w_ref: zero, or the load case's preload) and its loaded reading (w), a joint
whose torque changes sign travels its dead band: a displacement the joint-spring model
does not have. :func:`flank_changes` says which joints do; :func:`keeping_preload` the
smallest ``preload_fraction`` that keeps every joint of a test on one flank. Pure,
batched; the same rule as the simulated lab's (:func:`analysis.kinetostatics.realistic.flanks`).
"""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.realistic import FLANK_TOLERANCE, RealisticLab, flanks
from analysis.model.gravity import gravity_torques
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

#: the flank rule of a lab with lost motion: gravity decides, the springs are not loaded
_FLANKS = RealisticLab(gravity="flanks")


def flank_changes(robot: RobotModel, q: np.ndarray, w: np.ndarray,
                  w_ref: np.ndarray) -> np.ndarray:
    """(m, n) bool: joint j of test i rests on another flank (or leaves mid-band) between
    the reference reading under ``w_ref`` and the loaded reading under ``w`` (m, 6) at
    joint angles q (m, n) (rad, model convention). Needs the robot's mass model."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    return flanks(robot, _FLANKS, q, w_ref) != flanks(robot, _FLANKS, q, w)


def keeping_preload(robot: RobotModel, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(m,) the preload fraction f above which no joint of test i changes flank when the
    reference reading is taken under f w (0: none changes unloaded; nan: a joint carries
    no torque under the load, its flank is not decided).

    Per joint, the reference torque f a - g (a = (J^T w)_j, g = g_j) runs linearly from
    -g (f = 0) to the loaded a - g (f = 1); when its flank at f = 0 is not the loaded one
    s, it reaches that flank (|torque| > :data:`FLANK_TOLERANCE` with sign s) for
    f > (g + s tol) / a.
    """
    q = np.atleast_2d(np.asarray(q, dtype=float))
    a = np.einsum("pri,pr->pi", jacobian(robot, q),
                  np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6)))
    g = gravity_torques(robot, q)

    def side(t):
        return np.where(np.abs(t) <= FLANK_TOLERANCE, 0.0, np.sign(t))

    s_load = side(a - g)
    change = side(-g) != s_load
    with np.errstate(divide="ignore", invalid="ignore"):
        need = np.where(change & (s_load != 0),
                        (g + s_load * FLANK_TOLERANCE) / np.where(a == 0, 1.0, a), 0.0)
    out = np.max(need, axis=1)
    out[np.any(s_load == 0, axis=1)] = np.nan
    return out
