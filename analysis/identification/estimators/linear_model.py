"""The linear identification model of Dumas et al. 2011 (eqs. 14-21).

For one test (pose q, wrench w) the deflection screw is
``delta_d = J K_theta^-1 J^T w = A x`` with ``x = [1/k_1 .. 1/k_n]`` (rad/(N m))
and ``A[r, j] = J[r, j] * (J^T w)[j]`` (eqs. 16-18). Stacking n tests gives a
6n x n system.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg import lsq
from analysis.identification.streaming import per_test
from analysis.identification.streaming.per_test import PerTestDesign, PerTestJacobian, is_lazy
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


def design_block(J: np.ndarray, w: np.ndarray) -> np.ndarray:
    """A (..., 6, n) for Jacobians J (..., 6, n) and wrenches w (..., 6) (N, N m).

    Rows are [m/(rad/(N m))] for translations and [rad/(rad/(N m))] for rotations.
    """
    tau = np.einsum("...ji,...j->...i", J, np.asarray(w, dtype=float))
    return J * tau[..., None, :]


def design_matrix(robot: RobotModel, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Stacked A (6 m, n) for m tests: q (m, n) rad, w (m, 6) or (6,) (N, N m)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    w = np.broadcast_to(np.asarray(w, dtype=float), (q.shape[0], 6))
    blocks = design_block(jacobian(robot, q), w)
    return blocks.reshape(-1, blocks.shape[-1])


def predicted_deflection(robot: RobotModel, q: np.ndarray, w: np.ndarray, k: np.ndarray):
    """delta_d (..., 6) of the linear model (eq. 14) for joint stiffness k (N m/rad)."""
    J = jacobian(robot, q)
    return np.einsum("...rj,j->...r", design_block(J, w), 1.0 / np.asarray(k, dtype=float))


def jacobian_blocks(robot: RobotModel, q: np.ndarray):
    """J(q) (m, 6, 6) of the tests' joint angles ``q`` (m, 6) (rad).

    More than :data:`~analysis.identification.streaming.per_test.LAZY_TESTS` tests: a
    :class:`~analysis.identification.streaming.per_test.PerTestJacobian`, made block by block
    when sliced (0.3 GB not held at 1e6 tests). An identification makes it once
    (:attr:`analysis.identification.problem.IdentificationProblem.jacobian`) and passes
    it to every fit of the same joint angles.
    """
    q = np.asarray(q, dtype=float)
    if per_test.streamed(q.shape[-2], q.shape[:-2]):
        return PerTestJacobian(robot, q)
    # in blocks of tests: the chain state of many poses at once is ~2.6 kB per pose
    J = np.empty((*q.shape[:-1], 6, q.shape[-1]))
    for s in range(0, q.shape[0], lsq.TEST_BLOCK):
        J[s:s + lsq.TEST_BLOCK] = jacobian(robot, q[s:s + lsq.TEST_BLOCK])
    return J


def tests_design(robot: RobotModel, tests: TestArrays, joints: tuple[int, ...], J=None):
    """J (m, 6, 6) and the design A (m, 6, p) of ``joints`` (zero rows where not measured).

    A is filled block by block: no (m, 6, 6) temporaries beside J. For a large campaign
    both are made when sliced (:mod:`analysis.identification.streaming.per_test`). ``J``: the
    tests' :func:`jacobian_blocks` if the caller has it.
    """
    J = jacobian_blocks(robot, tests.q) if J is None else J
    cols = list(joints)
    if is_lazy(J):
        return J, PerTestDesign(J, tests.w, tests.measured, cols)
    A = np.empty((tests.m, 6, len(cols)))
    for s in range(0, tests.m, lsq.TEST_BLOCK):
        sl = slice(s, s + lsq.TEST_BLOCK)
        A[sl] = design_block(J[sl], tests.w[sl])[..., cols] * tests.measured[sl, :, None]
    return J, A
