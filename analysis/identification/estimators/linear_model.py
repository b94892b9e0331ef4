"""The linear identification model of Dumas et al. 2011 (eqs. 14-21).

For one test (pose q, wrench w) the deflection screw is
``delta_d = J K_theta^-1 J^T w = A x`` with ``x = [1/k_1 .. 1/k_n]`` (rad/(N m))
and ``A[r, j] = J[r, j] * (J^T w)[j]`` (eqs. 16-18). Stacking n tests gives a
6n x n system.
"""

from __future__ import annotations

import numpy as np

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
