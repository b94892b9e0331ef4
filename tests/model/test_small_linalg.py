"""The batched 6x6 kernels (elimination, QR-based ||M^-1||_F) against LAPACK and SVD,
and the fast map kernel against the reference composition of LAPACK calls."""

from __future__ import annotations

import numpy as np

from analysis.kinetostatics.dexterity import frobenius_condition
from analysis.kinetostatics.maps import WORST_CASE_WRENCH, GridSpec, pose_metrics
from analysis.kinetostatics.small_linalg import (
    diagonally_dominant,
    inverse_frobenius2,
    solve_dominant,
    to_entry_major,
)
from analysis.kinetostatics.stiffness import complementary_stiffness_from_jacobian
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot


def _dominant(rng, count, n=6):
    A = rng.normal(size=(count, n, n))
    A[:, np.arange(n), np.arange(n)] = np.abs(A).sum(axis=2) + rng.uniform(0.1, 1, (count, n))
    return A


def test_solve_dominant_matches_lapack_with_fallback():
    rng = np.random.default_rng(1)
    A = _dominant(rng, 200)
    A[::7] = rng.normal(size=(29, 6, 6))  # not dominant: must go to LAPACK
    b = rng.normal(size=(200, 6))
    E = to_entry_major(A)
    ok = diagonally_dominant(E)
    assert ok[np.arange(200) % 7 != 0].all()
    assert not ok[::7].any()  # standard normal 6x6 matrices are (almost surely here) not dominant
    x = solve_dominant(E, b.T.copy()).T
    ref = np.linalg.solve(A, b[..., None])[..., 0]
    # tolerance: a few ulps times the condition number of these well-conditioned matrices
    np.testing.assert_allclose(x, ref, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(np.einsum("nij,nj->ni", A, x), b, atol=1e-10)


def test_inverse_frobenius_matches_svd():
    rng = np.random.default_rng(2)
    M = rng.normal(size=(300, 6, 6))
    s = np.linalg.svd(M, compute_uv=False)
    ref = np.sum(1.0 / s**2, axis=-1)
    got = inverse_frobenius2(to_entry_major(M))
    # relative error ~ eps * cond(M); these have cond < 1e5
    assert np.max(s[:, 0] / s[:, -1]) < 1e5
    np.testing.assert_allclose(got, ref, rtol=1e-9)


def test_frobenius_condition_singular_is_inf_and_shapes_kept():
    M = np.eye(6)
    M[5, 5] = 0.0
    assert np.isinf(frobenius_condition(M))
    batch = np.stack([np.eye(6), M, np.diag([1.0, 2, 3, 4, 5, 6])]).reshape(3, 1, 6, 6)
    kappa = frobenius_condition(batch)
    assert kappa.shape == (3, 1)
    s = np.array([1.0, 2, 3, 4, 5, 6])
    assert kappa[0, 0] == 1.0 and np.isinf(kappa[1, 0])
    assert abs(kappa[2, 0] - np.sqrt(np.sum(s**2) * np.sum(1 / s**2)) / 6) < 1e-14


def test_kc_per_pose_wrench_matches_single_wrench():
    robot = load_robot("kr240-2")
    q = np.random.default_rng(3).uniform(-2, 2, (5, 6))
    J = jacobian(robot, q)
    w = np.random.default_rng(4).normal(size=(5, 6)) * 1e3
    both = complementary_stiffness_from_jacobian(J, w)
    one = np.stack([complementary_stiffness_from_jacobian(J[i], w[i]) for i in range(5)])
    np.testing.assert_allclose(both, one, rtol=1e-13, atol=1e-9)


def test_map_kernel_matches_reference_lapack_path():
    """Fast kernel (QR, elimination) = explicit inverse and LAPACK solve, on the 2 deg map."""
    robot = load_robot("kr240-2")
    k, w, L = robot.nominal_stiffness, WORST_CASE_WRENCH, 0.682
    q = GridSpec.from_limits(robot, np.radians(2.0)).poses().reshape(-1, 6)
    m = pose_metrics(robot, q, k, w, L, threads=1)
    J = jacobian(robot, q)
    JN = J * np.array([1 / L] * 3 + [1.0] * 3)[:, None]
    kappa = np.sqrt(np.sum(JN**2, axis=(1, 2)) * np.sum(np.linalg.inv(JN) ** 2, axis=(1, 2))) / 6
    ok = kappa < 1e8  # away from the singular lines both are accurate to eps * kappa
    np.testing.assert_allclose(m["inv_kappa_F"][ok], 1 / kappa[ok], rtol=1e-8)
    K_C = complementary_stiffness_from_jacobian(J, w)
    tau = np.einsum("nji,j->ni", J, w)
    d_kc = np.einsum("nij,nj->ni", J, np.linalg.solve(np.diag(k) - K_C, tau[..., None])[..., 0])
    d_no = np.einsum("nij,nj->ni", J, tau / k)
    a, b = np.linalg.norm(d_kc[:, :3], axis=1), np.linalg.norm(d_no[:, :3], axis=1)
    np.testing.assert_allclose(m["deflection"], d_kc, rtol=1e-10, atol=1e-15)
    np.testing.assert_allclose(m["v_p"], np.abs(a - b) / np.maximum(a, b), rtol=1e-8, atol=1e-14)
    np.testing.assert_allclose(m["v_r"], np.abs(d_kc[:, 3:] - d_no[:, 3:]).max(axis=1),
                               rtol=1e-8, atol=1e-16)
    threaded = pose_metrics(robot, q, k, w, L, threads=2)
    np.testing.assert_array_equal(threaded["v_p"], m["v_p"])
