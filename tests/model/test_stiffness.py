"""K_C, K_X, deflection and the influence indices against independent computations."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import SingularPoseError
from analysis.kinetostatics.equilibrium import displacement_screw, solve_deflection
from analysis.kinetostatics.maps import WORST_CASE_WRENCH, GridSpec, pose_metrics
from analysis.kinetostatics.stiffness import (
    cartesian_compliance,
    cartesian_stiffness,
    complementary_stiffness,
    deflection,
    kc_influence,
)
from analysis.model.kinematics import jacobian
from analysis.model.robots import builtin_names, load_robot

K_GENERIC = np.array([2.0e6, 1.5e6, 1.0e6, 4.0e5, 3.0e5, 2.0e5])


def _stiffness(robot):
    return robot.nominal_stiffness if robot.nominal_stiffness is not None else K_GENERIC


def _fd_kc(robot, q, w, h=1e-6):
    out = np.zeros((robot.n, robot.n))
    for i in range(robot.n):
        e = np.zeros(robot.n)
        e[i] = h
        out[:, i] = (jacobian(robot, q + e).T @ w - jacobian(robot, q - e).T @ w) / (2 * h)
    return out


@pytest.mark.parametrize("name", builtin_names())
def test_kc_matches_finite_differences(name):
    robot = load_robot(name)
    rng = np.random.default_rng(2)
    for _ in range(4):
        q = rng.uniform(np.maximum(robot.lower, -3), np.minimum(robot.upper, 3))
        w = rng.normal(size=6) * [1000, 1000, 1000, 100, 100, 100]
        K_C = complementary_stiffness(robot, q, w)
        fd = _fd_kc(robot, q, w)
        assert np.abs(K_C - fd).max() < 1e-6 * max(1.0, np.abs(fd).max())


def test_kc_batched_equals_single():
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(4)
    qs = rng.uniform(robot.lower, robot.upper, size=(7, 6))
    ws = rng.normal(size=(7, 6)) * 1000
    batch = complementary_stiffness(robot, qs, ws)
    for i in range(7):
        np.testing.assert_allclose(batch[i], complementary_stiffness(robot, qs[i], ws[i]),
                                   atol=1e-9)


@pytest.mark.parametrize("name", ["kr240-2", "puma560", "ur10e"])
def test_kx_is_tangent_of_nonlinear_equilibrium_at_loaded_pose(name):
    """K_X^-1 (J, K_C at q + dq) equals d(dX)/dw of the equilibrium to ~1e-10; at the
    unloaded pose it differs by the order of the K_C effect itself (~0.1-2 %)."""
    robot = load_robot(name)
    k = _stiffness(robot)
    scale = 1.0 if name == "kr240-2" else 0.005 if name == "puma560" else 0.5
    w = WORST_CASE_WRENCH * scale
    q = np.radians([10, 40, -100, 30, 50, 20]) if name != "kr240-2" else np.radians(
        [10, 40, -200, 30, 50, 20])
    dq = solve_deflection(robot, q, k, w)
    ql = q + dq
    J_l = jacobian(robot, ql)
    C_t = np.zeros((6, 6))
    hw = 1e-2 * np.abs(w).max() / 2200
    for i in range(6):
        e = np.zeros(6)
        e[i] = hw
        C_t[:, i] = J_l @ (solve_deflection(robot, q, k, w + e)
                           - solve_deflection(robot, q, k, w - e)) / (2 * hw)
    K_X = cartesian_stiffness(J_l, k, complementary_stiffness(robot, ql, w))
    rel = np.abs(np.linalg.inv(K_X) - C_t).max() / np.abs(C_t).max()
    assert rel < 1e-8
    K_X0 = cartesian_stiffness(jacobian(robot, q), k, complementary_stiffness(robot, q, w))
    rel0 = np.abs(np.linalg.inv(K_X0) - C_t).max() / np.abs(C_t).max()
    assert 1e-5 < rel0 < 0.05


def test_equilibrium_residual_and_linear_limit():
    robot = load_robot("kr240-2")
    k = robot.nominal_stiffness
    q = np.radians([0, 30, 10, 45, 45, 45])
    w = WORST_CASE_WRENCH
    dq = solve_deflection(robot, q, k, w)
    resid = k * dq - jacobian(robot, q + dq).T @ w
    assert np.abs(resid).max() < 1e-8
    # small wrench: finite displacement -> linear deflection, error second order in w
    for s in (1e-2, 1e-3):
        lin = deflection(jacobian(robot, q), k, w * s)
        fin = displacement_screw(robot, q, k, w * s)
        assert np.abs(fin - lin).max() / np.abs(lin).max() < 0.02 * s


def test_compliance_is_inverse_of_stiffness_and_symmetric_without_kc():
    robot = load_robot("kr240-2")
    J = jacobian(robot, np.radians([0, 30, 10, 45, 45, 45]))
    k = robot.nominal_stiffness
    K = cartesian_stiffness(J, k)
    C = cartesian_compliance(J, k)
    np.testing.assert_allclose(K @ C, np.eye(6), atol=1e-9)
    np.testing.assert_allclose(K, K.T, rtol=1e-10, atol=1e-6)


def test_singular_pose_refused_for_kx():
    robot = load_robot("ur5e")
    q = np.zeros(6)  # UR at zero: arm stretched, shoulder/elbow singular
    with pytest.raises(SingularPoseError):
        cartesian_stiffness(jacobian(robot, q), K_GENERIC)
    m = pose_metrics(robot, q, K_GENERIC, WORST_CASE_WRENCH, 0.5)
    assert m["singular"] and m["inv_kappa_F"] == 0.0
    assert np.isfinite(m["v_p"]) and np.isfinite(m["v_r"])


def test_kr240_kc_influence_matches_paper_bounds():
    """Paper section 3: with Table 2 and the worst-case wrench, v_p <= 0.016 and
    v_r <= 0.025 deg over (theta2, theta3) (theta1 = 0, wrist at 45 deg). Our geometry
    (kr240-2.toml) gives max v_p = 0.0173 and max v_r = 0.0157 deg on a 1 deg grid."""
    robot = load_robot("kr240-2")
    grid = GridSpec.from_limits(robot, np.radians(1.0))
    m = pose_metrics(robot, grid.poses(), robot.nominal_stiffness, WORST_CASE_WRENCH, 0.682)
    ok = ~m["singular"]
    v_p = m["v_p"][ok].max()
    v_r = np.degrees(m["v_r"][ok].max())
    assert 0.015 < v_p < 0.019
    assert 0.005 < v_r <= 0.025


def test_kc_influence_batched_equals_map():
    robot = load_robot("kr240-2")
    q = np.radians([[0, 20, 10, 45, 45, 45], [0, 120, -200, 45, 45, 45]])
    v_p, v_r = kc_influence(robot, q, robot.nominal_stiffness, WORST_CASE_WRENCH)
    m = pose_metrics(robot, q, robot.nominal_stiffness, WORST_CASE_WRENCH, 0.682)
    np.testing.assert_allclose(v_p, m["v_p"])
    np.testing.assert_allclose(v_r, m["v_r"])
    # direct from the definition (eq. 10)
    J = jacobian(robot, q[0])
    K_C = complementary_stiffness(robot, q[0], WORST_CASE_WRENCH)
    a = np.linalg.norm(deflection(J, robot.nominal_stiffness, WORST_CASE_WRENCH, K_C)[:3])
    b = np.linalg.norm(deflection(J, robot.nominal_stiffness, WORST_CASE_WRENCH)[:3])
    assert v_p[0] == pytest.approx(abs(a - b) / max(a, b), rel=1e-12)
