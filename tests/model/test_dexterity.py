"""Condition number (eq. 3), normalized Jacobian (eq. 4) and characteristic length."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.kinetostatics.dexterity import (
    characteristic_length,
    frobenius_condition,
    inverse_condition,
    normalized_jacobian,
)
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot


def test_frobenius_condition_known_values():
    assert frobenius_condition(np.eye(6)) == pytest.approx(1.0)
    D = np.diag([1.0, 2.0])
    # (1/2) sqrt((1 + 4) (1 + 1/4)) = 1.25
    assert frobenius_condition(D) == pytest.approx(1.25)
    rng = np.random.default_rng(0)
    M = rng.normal(size=(50, 6, 6))
    direct = np.array([np.sqrt(np.trace(m.T @ m) * np.trace(np.linalg.inv(m.T @ m))) / 6
                       for m in M])
    np.testing.assert_allclose(frobenius_condition(M), direct, rtol=1e-10)


def test_singular_gives_zero_inverse_condition_not_nan():
    M = np.stack([np.eye(6), np.diag([1, 1, 1, 1, 1, 0.0])])
    inv = inverse_condition(M)
    assert inv[0] == pytest.approx(1.0)
    assert inv[1] == 0.0


def test_normalized_jacobian_scales_translation_rows():
    robot = load_robot("kr240-2")
    J = jacobian(robot, np.radians([0, 30, 10, 45, 45, 45]))
    JN = normalized_jacobian(J, 0.682)
    np.testing.assert_allclose(JN[:3], J[:3] / 0.682)
    np.testing.assert_allclose(JN[3:], J[3:])


def test_characteristic_length_is_a_local_optimum():
    """Khan-Angeles characteristic length of our KR240-2 geometry: 0.700 m (kappa_F =
    1.285), within 3 % of the paper's 0.682 m (their geometry numbers are not published)."""
    robot = load_robot("kr240-2")
    L, q, kmin = characteristic_length(robot)
    assert L == pytest.approx(0.682, rel=0.03)
    assert kmin < 1.29
    for factor in (0.9, 1.1):
        J = jacobian(robot, q)
        assert frobenius_condition(normalized_jacobian(J, L * factor)) >= kmin - 1e-9
