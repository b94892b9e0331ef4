"""The entry-major kinematics and Newton kernels against independent computations:
products of 4 x 4 transforms, extended-precision cos/sin, Pinocchio's Jacobian in the
equilibrium residual, LAPACK for the LU kernels."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

from analysis.kinetostatics.equilibrium import newton_deflection, newton_deflection_em
from analysis.kinetostatics.small_linalg import lu_em, lu_solve_em, lu_solve_right_em
from analysis.model.kinematics import (
    chain_state,
    chain_state_em,
    jacobian_em,
    jacobian_from_state,
    joint_cos_sin,
    pin_jacobian,
)
from analysis.model.robot_model import Chain
from analysis.model.robots import load_robot


def _transform(R, p):
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T


def test_general_chain_equals_the_product_of_joint_transforms():
    """Tilted axes, placements that are not signed permutations, a tool: origins, axes,
    tool pose and J equal those of the product of 4 x 4 transforms (Rodrigues for each
    joint), to 1e-14 m."""
    rng = np.random.default_rng(3)
    n = 6
    axes = rng.normal(size=(n, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    axes[1] = [0.0, 1.0, 0.0]  # a coordinate axis other than z
    place = np.array([_transform(pin.exp3(rng.normal(size=3)), rng.normal(size=3) * 0.5)
                      for _ in range(n)])
    place[2, :3, :3] = [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]
    tip = _transform(pin.exp3(rng.normal(size=3)), [0.1, -0.2, 0.3])
    robot = SimpleNamespace(chain=Chain(place, axes, tip))
    q = rng.uniform(-np.pi, np.pi, (50, n))
    state = chain_state(robot, q)
    J = jacobian_from_state(state)
    for k in range(len(q)):
        T = np.eye(4)
        for i in range(n):
            T = T @ place[i]
            np.testing.assert_allclose(state.origins[k, i], T[:3, 3], atol=1e-14)
            np.testing.assert_allclose(state.axes[k, i], T[:3, :3] @ axes[i], atol=1e-14)
            T = T @ _transform(pin.exp3(axes[i] * q[k, i]), np.zeros(3))
        T = T @ tip
        np.testing.assert_allclose(state.tip[k], T, atol=1e-14)
        # J column i = [w_i x (p - o_i); w_i]
        lin = np.cross(state.axes[k], T[:3, 3] - state.origins[k])
        np.testing.assert_allclose(J[k], np.vstack([lin.T, state.axes[k].T]), atol=1e-14)
    em = chain_state_em(robot, q.T)
    np.testing.assert_array_equal(np.moveaxis(jacobian_em(em), -1, 0), J)


@pytest.mark.parametrize("scale", [1e-12, 1e-4, 1e-2, 0.1])
def test_cos_sin_of_deflected_angles_match_extended_precision(scale):
    """Angle sums with series: within 2e-16 of cos/sin of q + dq in extended precision
    (np.cos of the rounded sum q + dq is within ~2.5e-16); above 0.1 rad np.cos is used."""
    rng = np.random.default_rng(5)
    q = rng.uniform(-np.pi, np.pi, (6, 4000))
    dq = rng.uniform(-scale, scale, q.shape)
    c, s = joint_cos_sin(q, dq, (np.cos(q), np.sin(q)))
    exact = q.astype(np.longdouble) + dq.astype(np.longdouble)
    if np.finfo(np.longdouble).eps >= np.finfo(float).eps:
        pytest.skip("no extended precision on this platform")
    assert np.max(np.abs(c - np.cos(exact))) < 2e-16
    assert np.max(np.abs(s - np.sin(exact))) < 2e-16
    big = dq.copy()
    big[0, 0] = 0.2
    c2, s2 = joint_cos_sin(q, big, (np.cos(q), np.sin(q)))
    np.testing.assert_array_equal(c2, np.cos(q + big))
    np.testing.assert_array_equal(s2, np.sin(q + big))


@pytest.fixture(scope="module")
def loaded():
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(8)
    q = rng.uniform(robot.lower, robot.upper, (300, 6)) * 0.7
    w = rng.normal(size=(300, 6)) * np.r_[[2000.0] * 3, [300.0] * 3]
    return robot, q, 1.0 / np.asarray(robot.nominal_stiffness), w


def test_newton_solves_the_equilibrium_with_pinocchio_jacobian(loaded):
    """dq = x J(q + dq)^T w with J from Pinocchio (an independent kinematics), to the
    Newton tolerance; each pose's result does not depend on the other poses of the batch
    (a pose stops iterating when it has converged)."""
    robot, q, x, w = loaded
    dq, bad, last = newton_deflection(robot, q, x, w, 1e-15)
    assert not bad.any() and np.all(last <= 1e-15)
    assert np.max(np.abs(dq)) > 1e-3  # loads that matter
    for k in range(0, len(q), 15):
        J = pin_jacobian(robot, q[k] + dq[k])
        np.testing.assert_allclose(dq[k], x * (J.T @ w[k]), rtol=0, atol=2e-15)
    alone = np.stack([newton_deflection(robot, q[k], x, w[k], 1e-15)[0]
                      for k in range(0, len(q), 15)])
    np.testing.assert_allclose(alone, dq[::15], rtol=0, atol=1e-18)


def test_kept_state_and_lu_factors_belong_to_the_last_iterate(loaded):
    """``keep``: the kept iterate is within the last step of the solution; its J is the
    Jacobian there, and the LU factors multiply back to I - X K_C."""
    robot, q, x, w = loaded
    keep: dict = {}
    qe, we = np.ascontiguousarray(q.T), np.ascontiguousarray(w.T)
    dq, bad, last = newton_deflection_em(robot, qe, x[:, None], we, 1e-15, keep=keep)
    assert not bad.any()
    assert np.all(np.abs(keep["dq"] - dq).max(axis=0) <= last + 1e-18)
    Jk = jacobian_from_state(chain_state(robot, (qe + keep["dq"]).T))
    np.testing.assert_allclose(np.moveaxis(keep["J"], -1, 0), Jk, atol=1e-14)
    LU = np.moveaxis(keep["lu"], -1, 0)
    L = np.tril(LU, -1) + np.eye(6)
    np.testing.assert_allclose(L @ np.triu(LU), np.moveaxis(keep["dF"], -1, 0), atol=1e-14)


def test_lu_kernels_equal_lapack():
    rng = np.random.default_rng(2)
    N = 200
    A = np.eye(6)[:, :, None] + 0.15 * rng.normal(size=(6, 6, N))
    LU = lu_em(A.copy())
    Ab = np.moveaxis(A, -1, 0)
    B = rng.normal(size=(6, 4, N))
    X = lu_solve_em(LU, B.copy())
    np.testing.assert_allclose(np.moveaxis(X, -1, 0),
                               np.linalg.solve(Ab, np.moveaxis(B, -1, 0)), atol=1e-13)
    D = rng.normal(size=(5, 6, N))
    G = lu_solve_right_em(LU, D)
    np.testing.assert_allclose(np.moveaxis(G, -1, 0),
                               np.moveaxis(D, -1, 0) @ np.linalg.inv(Ab), atol=1e-13)
