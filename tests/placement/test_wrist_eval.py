"""The spherical-wrist fast path against the general kinematics, and the angle selection
against brute force."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from analysis.model.ik import ALL_FLAGS, IKSolver
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot, with_tool
from analysis.placement.evaluate import KEEP_OUT, LIMITS, OK, UNREACHABLE, Problem, evaluate
from analysis.placement.poses import base_wrench, target_poses
from analysis.placement.select import choose_angles

K = np.array([3e6, 2e6, 1.5e6, 4e5, 3e5, 2e5])
TOOLS = {  # the wrist centre on the tool axis (arm shared by the angles) or off it
    "kr240-2": (np.zeros(3), np.zeros(3)),
    "kr240-2 axial tool": (np.array([0.0, 0.0, 0.3]), np.zeros(3)),
    "kr240-2 offset tool": (np.array([0.05, -0.03, 0.25]), np.array([0.1, -0.2, 0.3])),
}


def _robot(name):
    if name in TOOLS:
        return with_tool(load_robot("kr240-2"), *TOOLS[name])
    return load_robot(name)


def _problem(robot, objective, cov=False, keep_out=False):
    n = 10
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = np.stack([0.15 * np.cos(t), 0.1 * np.sin(t), 0.02 * np.sin(2 * t)], axis=1)
    axes = np.stack([0.2 * np.cos(t), 0.1 * np.sin(t), -np.ones(n)], axis=1)
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    wrench = np.random.default_rng(1).normal(size=(n, 6)) * [300, 300, 300, 20, 20, 20]
    return Problem(robot=robot, points=pts, axes=axes,
                   wrench=None if objective == "compliance" else wrench,
                   angles=np.radians(np.arange(0, 360, 30.0)), k=K, length=0.7,
                   min_inv_kappa=0.05, margin=np.radians(2), max_step=np.radians(10),
                   objective=objective, flags=ALL_FLAGS,
                   keep_out=np.array([[-3.0, 3.0], [0.1, 3.0], [-3.0, 3.0]]) if keep_out else None,
                   cov_x=np.diag((0.05 / K) ** 2) + 1e-5 * np.outer(1 / K, 1 / K) if cov else None)


@pytest.mark.parametrize("name", [*TOOLS, "fanuc-s420f", "puma560"])
@pytest.mark.parametrize("objective,cov,keep_out", [("max", False, False), ("rms", True, False),
                                                    ("compliance", False, True)])
def test_fast_path_equals_general_kinematics(name, objective, cov, keep_out):
    robot = _robot(name)
    solver = IKSolver.for_robot(robot)
    assert solver.kind == "spherical_wrist"
    problem = _problem(robot, objective, cov, keep_out)
    x0, x1 = {"fanuc-s420f": (2.0, 2.4), "puma560": (0.3, 0.6)}.get(name, (1.2, 1.9))
    rng = np.random.default_rng(7)
    G = np.column_stack([rng.uniform(x0, x1, 6), rng.uniform(-0.3, 0.3, 6),
                         rng.uniform(-0.4, 0.4, 6), rng.uniform(-1, 1, 6)])
    G = np.vstack([G, [x1 + 2.0, 0.0, 0.0, 0.0]])  # out of reach
    feasible = 0
    reasons = set()
    for flags in ALL_FLAGS:
        fast = evaluate(problem, solver, G, flags)
        ref = evaluate(problem, solver, G, flags, general=True)
        np.testing.assert_array_equal(fast.reason, ref.reason)
        ok = ref.reason == OK
        feasible += ok.sum()
        reasons |= set(np.unique(ref.reason).tolist())
        np.testing.assert_allclose(fast.q[ok], ref.q[ok], rtol=0, atol=1e-12)
        np.testing.assert_allclose(fast.cost[ok], ref.cost[ok], rtol=1e-12, atol=0)
        np.testing.assert_allclose(fast.dp[ok], ref.dp[ok], rtol=0,
                                   atol=1e-12 * max(np.abs(ref.dp[ok]).max(initial=0), 1e-30))
        assert np.all(np.isinf(fast.cost[~ok]))
    assert feasible > 50  # the comparison is not vacuous
    assert reasons >= ({OK, UNREACHABLE, LIMITS} | ({KEEP_OUT} if keep_out else set()))


def test_fast_deflection_is_j_k_inverse_j_transpose_w():
    """Independent of both evaluation paths: dp = J_t K^-1 J^T w from kinematics.jacobian."""
    robot = _robot("kr240-2 offset tool")
    solver = IKSolver.for_robot(robot)
    problem = _problem(robot, "max")
    G = np.array([[1.6, 0.1, 0.3, 0.4], [1.8, -0.2, 0.0, -1.0]])
    tr = evaluate(problem, solver, G, (-1, -1, -1))
    ok = tr.reason == OK
    assert ok.sum() > 20
    T = target_poses(G, problem.points, problem.rotations)
    w = base_wrench(T[..., :3, :3], problem.wrench[:, None, :])
    J = jacobian(robot, tr.q[ok])
    expected = np.einsum("mij,mj->mi", J[:, :3] / K, np.einsum("mji,mj->mi", J, w[ok]))
    np.testing.assert_allclose(tr.dp[ok], expected, rtol=0, atol=1e-12 * np.abs(expected).max())


def _brute_force(cost, q, max_step, mode):
    B, N, A = cost.shape
    best = np.full(B, np.inf)
    for b in range(B):
        for seq in itertools.product(range(A), repeat=N):
            steps = [np.abs(np.angle(np.exp(1j * (q[b, n, seq[n]] - q[b, n - 1, seq[n - 1]]))))
                     for n in range(1, N)]
            if any(np.max(s) > max_step for s in steps):
                continue
            c = cost[b, np.arange(N), list(seq)]
            v = np.sqrt(np.mean(c**2)) if mode == "rms" else np.max(c)
            best[b] = min(best[b], v)
    return best


@pytest.mark.parametrize("mode", ["max", "rms"])
def test_angle_selection_equals_brute_force(mode):
    rng = np.random.default_rng(5)
    B, N, A = 6, 4, 4
    q = rng.uniform(-0.4, 0.4, size=(B, N, A, 6))
    q[..., 3] += rng.choice([-np.pi, np.pi], size=(B, N, A))  # joint 4 near +-pi: wraps
    turn = 2 * np.pi * (rng.random((B, N, A)) > 0.5)
    q[..., 5] = np.pi - 0.05 + 0.1 * rng.random((B, N, A)) - turn  # joint 6 on both sides of pi
    cost = rng.uniform(1, 2, size=(B, N, A))
    cost[rng.random((B, N, A)) > 0.8] = np.inf
    value, index, stuck = choose_angles(cost, q, 0.6, mode)
    np.testing.assert_allclose(value, _brute_force(cost, q, 0.6, mode), rtol=1e-12)
    assert np.isfinite(value).sum() >= 2
    # the returned sequence attains the value and is continuous
    for b in np.flatnonzero(np.isfinite(value)):
        c = cost[b, np.arange(N), index[b]]
        assert (np.sqrt(np.mean(c**2)) if mode == "rms" else c.max()) == pytest.approx(value[b])
        assert stuck[b] == -1
