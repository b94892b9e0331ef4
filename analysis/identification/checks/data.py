"""Checks of the tests before any fit: can they identify the joints at all?

:func:`check_tests` refuses rows that cannot be used (non-finite angles or wrench,
unmeasured rows, one pose only), naming the line and column; :func:`check_identifiable`
refuses a design whose column-scaled condition number exceeds :data:`COND_LIMIT`,
naming the weakest joint.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import InputError
from analysis.identification.io.columns import COMPONENTS, Q_COLS, W_COLS
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg import lsq
from analysis.identification.linalg.lsq import scaled_condition, weakest_column
from analysis.identification.noise import NoiseModel
from analysis.identification.poses import POSE_TOLERANCE_SIGMAS, count_poses, pose_tolerance
from analysis.identification.streaming.per_test import is_lazy
from analysis.model.robot_model import RobotModel

COND_LIMIT = 1e6

def check_tests(robot: RobotModel, tests: TestArrays, joints: tuple[int, ...],
                noise: NoiseModel | None = None, group: np.ndarray | None = None) -> None:
    """Refuse data that cannot identify ``joints``; messages name the line, column or joint.

    Poses are told apart by :mod:`analysis.identification.poses` (joint angles
    equal to within the encoder noise of ``noise``); ``group``: the tests' pose groups
    (:func:`~analysis.identification.poses.pose_groups`) if the caller has them.
    """
    if robot.n != 6:
        raise InputError(f"{robot.name} has {robot.n} joints; the test format has 6")
    for name, arr, cols in (("joint angles", tests.q, Q_COLS), ("wrench", tests.w, W_COLS)):
        bad = ~np.isfinite(arr)
        if np.any(bad):
            i, j = np.argwhere(bad)[0]
            raise InputError(f"line {tests.line[i]}, column {cols[j]}: {name} must be finite")
    bad = np.isinf(tests.d) | (np.isnan(tests.d) & tests.measured)
    if np.any(bad):
        i, j = np.argwhere(bad)[0]
        raise InputError(f"line {tests.line[i]}, component {COMPONENTS[j]}: displacement must "
                         "be finite where measured")
    zero = np.all(tests.w == 0.0, axis=1)
    if np.any(zero):
        i = int(np.flatnonzero(zero)[0])
        raise InputError(f"line {tests.line[i]}, columns {', '.join(W_COLS)}: zero wrench; a "
                         "test needs a load")
    tol = 1e-9
    out = (tests.q < robot.lower - tol) | (tests.q > robot.upper + tol)
    if np.any(out):
        i, j = np.argwhere(out)[0]
        raise InputError(
            f"line {tests.line[i]}, column {Q_COLS[j]}: {np.degrees(tests.q[i, j]):.3f} deg is "
            f"outside the limits of {robot.name} [{np.degrees(robot.lower[j]):.1f}, "
            f"{np.degrees(robot.upper[j]):.1f}] deg (model convention; a controller-angle mix-up?)",
        )
    n_eq = int(tests.measured.sum())
    if n_eq < len(joints):
        raise InputError(
            f"{n_eq} measured displacement components for {len(joints)} unknown joint "
            f"compliances: fewer equations than unknowns; add tests"
        )
    tol = pose_tolerance(noise)
    n_poses = count_poses(tests.q, tol) if group is None else int(group.max(initial=-1)) + 1
    if n_poses < 2:
        raise InputError(
            f"all {tests.m} tests (lines {tests.line[0]}..{tests.line[-1]}, columns "
            f"{Q_COLS[0]}..{Q_COLS[-1]}) are at one pose (joint angles equal to within "
            f"{np.degrees(tol):.2g} deg, {POSE_TOLERANCE_SIGMAS:g} encoder sigmas): errors of "
            "the kinematic model and tool point cannot be told from compliance, and nothing "
            "can be validated; measure at two poses or more"
        )


def check_identifiable(
    A: np.ndarray, joints: tuple[int, ...], cond_limit: float = COND_LIMIT
) -> float:
    """Condition number of the column-scaled A (m, 6, p); refuse naming the weakest joint."""
    # one pass: a tall A's R has its column norms and singular values (Householder QR's
    # backward error is column-wise, so scaling after it loses nothing)
    acc = lsq.StackedRows(6 * A.shape[0], tall=is_lazy(A))
    for s in range(0, A.shape[0], lsq.TEST_BLOCK):
        acc.add(A[s:s + lsq.TEST_BLOCK].reshape(-1, A.shape[-1]))
    stacked = acc.matrix()
    norms = np.linalg.norm(stacked, axis=0)
    if np.any(norms == 0):
        j = joints[int(np.flatnonzero(norms == 0)[0])]
        raise InputError(
            f"joint {j + 1} cannot be identified: no test moves the tool through it "
            f"(its column of A is zero: no torque on joint {j + 1}, or no measured component "
            "it moves); take it as rigid with --joints or add tests that load it",
            where="--joints",
        )
    cond = float(scaled_condition(stacked))
    if not cond <= cond_limit:
        j = joints[weakest_column(stacked)]
        raise InputError(
            f"joint {j + 1} cannot be identified from these tests: the condition number of "
            f"the column-scaled A is {cond:.3g} (limit {cond_limit:.0e}) and joint {j + 1} "
            "dominates its null direction; take it as rigid with --joints or add poses",
            where="--joints",
        )
    return cond
