"""The fused map kernel (issue 36) against the equations written out pose by pose here:
J from Pinocchio, K_C from eq. 8's closed form, kappa_F from an explicit inverse, the
deflections from LAPACK's solve, v_p and v_r from eqs. 10-11."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.kinetostatics.map_kernel import dominance_proved, grid_cos_sin
from analysis.kinetostatics.maps import WORST_CASE_WRENCH, pose_metrics
from analysis.model.kinematics import pin_jacobian, pin_tool_pose
from analysis.model.robots import load_robot

LENGTH = 0.682  # m, the paper's characteristic length (any positive value would do)
#: the two robot files: the paper's KR240-2 (its nominal k, the paper's worst-case wrench)
#: and a UR10e, whose file has no stiffness: a plausible k (N m/rad) and a tenth of the wrench
ROBOTS = {"kr240-2": (None, WORST_CASE_WRENCH),
          "ur10e": (np.array([3e5, 3e5, 2e5, 5e4, 5e4, 5e4]), WORST_CASE_WRENCH / 10)}


def setup(name):
    """(robot, k, w) of one of :data:`ROBOTS`."""
    robot = load_robot(name)
    k, w = ROBOTS[name]
    return robot, (robot.nominal_stiffness if k is None else k), w


def reference(robot, q: np.ndarray, k: np.ndarray, w: np.ndarray, length: float) -> dict:
    """The map's figures at poses q (N, n) from the equations, one pose at a time."""
    out = {key: [] for key in ("inv_kappa_F", "v_p", "v_r", "deflection", "position")}
    n = robot.n
    for qi in q:
        J = pin_jacobian(robot, qi)
        v, om = J[:3], J[3:]
        K_C = np.empty((n, n))
        for i in range(n):
            for j in range(n):
                if j <= i:  # dJ_i/dq_j = [om_j x v_i; om_j x om_i]
                    dJ = np.r_[np.cross(om[:, j], v[:, i]), np.cross(om[:, j], om[:, i])]
                else:  # dJ_i/dq_j = [om_i x v_j; 0]
                    dJ = np.r_[np.cross(om[:, i], v[:, j]), np.zeros(3)]
                K_C[i, j] = dJ @ w
        JN = np.diag([1.0 / length] * 3 + [1.0] * 3) @ J
        kappa = np.linalg.norm(JN) * np.linalg.norm(np.linalg.inv(JN)) / n
        tau = J.T @ w
        d_kc = J @ np.linalg.solve(np.diag(k) - K_C, tau)
        d_no = J @ (tau / k)
        a, b = np.linalg.norm(d_kc[:3]), np.linalg.norm(d_no[:3])
        out["inv_kappa_F"].append(1.0 / kappa)
        out["v_p"].append(abs(a - b) / max(a, b))
        out["v_r"].append(np.max(np.abs(d_kc[3:] - d_no[3:])))
        out["deflection"].append(d_kc)
        out["position"].append(pin_tool_pose(robot, qi)[:3, 3])
    return {key: np.array(val) for key, val in out.items()}


def assert_same(got: dict, ref: dict, rtol: float = 1e-12) -> None:
    """Every figure within rtol relative; a screw's entries relative to its largest entry
    of the same kind (translation, rotation) at that pose. v_p = |a - b| / max(a, b) of
    two nearly equal norms carries their rounding (~1e-16) as an absolute error, so it
    is also allowed 1e-15 absolute (J from Pinocchio and from the kernel's chain differ
    in the last bits)."""
    for key, atol in (("inv_kappa_F", 0.0), ("v_p", 1e-15), ("v_r", 0.0)):
        np.testing.assert_allclose(got[key].ravel(), ref[key], rtol=rtol, atol=atol,
                                   err_msg=key)
    d, dr = got["deflection"].reshape(-1, 6), ref["deflection"]
    for part in (slice(0, 3), slice(3, 6)):
        scale = np.abs(dr[:, part]).max(axis=1, keepdims=True)
        assert np.max(np.abs(d[:, part] - dr[:, part]) / scale) < rtol
    p, pr = got["position"].reshape(-1, 3), ref["position"]
    assert np.max(np.abs(p - pr)) < rtol * np.abs(pr).max()


def random_poses(robot, count: int, seed: int) -> np.ndarray:
    """Poses uniform over the middle 80 % of the joint ranges (away from the limits' wrist
    singularities), seeded: well-conditioned enough that both sides agree to 1e-12."""
    lo, hi = robot.map_limits()
    mid, half = (lo + hi) / 2, 0.4 * (hi - lo)
    return np.random.default_rng(seed).uniform(mid - half, mid + half, (count, robot.n))


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_kernel_equals_the_equations_on_random_poses(name):
    robot, k, w = setup(name)
    q = random_poses(robot, 150, seed=1)
    got = pose_metrics(robot, q, k, w, LENGTH, threads=1)
    ref = reference(robot, q, k, w, LENGTH)
    assert np.all(ref["inv_kappa_F"] > 1e-3)  # the sample is what the docstring says
    assert_same(got, ref)


@pytest.mark.parametrize("name", sorted(ROBOTS))
def test_kernel_equals_the_equations_on_a_map_grid(name):
    """A (theta_2, theta_3) grid with the other joints fixed: the fixed joints' cos and sin
    are floats, theta_2's and theta_3's are computed along one grid axis each."""
    robot, k, w = setup(name)
    q = np.broadcast_to(np.radians([10.0, 0, 0, 45, 45, 45]), (7, 9, 6)).copy()
    q[..., 1] = np.radians(np.linspace(-60, 20, 7))[:, None]
    q[..., 2] = np.radians(np.linspace(-100, 40, 9))[None, :]
    got = pose_metrics(robot, q, k, w, LENGTH, threads=1)
    assert got["v_p"].shape == (7, 9) and got["deflection"].shape == (7, 9, 6)
    assert_same(got, reference(robot, q.reshape(-1, 6), k, w, LENGTH), rtol=1e-12)


def test_grid_cos_sin_values_and_kinds():
    q = np.zeros((3, 4, 6))
    q[..., 0] = 0.3  # fixed: a float
    q[..., 1] = np.arange(3)[:, None]  # along axis 0 only: computed 3 times, spread
    q[..., 2] = np.arange(4)[None, :] * 0.5
    q[..., 3:] = np.random.default_rng(0).normal(size=(3, 4, 3))  # varies everywhere
    trig = grid_cos_sin(q)
    assert isinstance(trig.cos[0], float) and trig.cos[0] == np.cos(0.3)
    assert trig.cos[1].shape == (12,) and trig.cos[3] is None
    flat = q.reshape(-1, 6)
    cos, sin = trig.block(flat[5:11], 5)
    for j in range(6):
        np.testing.assert_array_equal(np.broadcast_to(cos[j], (6,)), np.cos(flat[5:11, j]))
        np.testing.assert_array_equal(np.broadcast_to(sin[j], (6,)), np.sin(flat[5:11, j]))


def test_dominance_bound_holds_and_the_other_path_agrees():
    """The bound of dominance_proved is above every row of |K_C| met (an independent
    check), and a wrench too large for it takes the pose-by-pose path, with the same
    figures as the equations."""
    robot = load_robot("kr240-2")
    k, w = robot.nominal_stiffness, WORST_CASE_WRENCH
    assert dominance_proved(robot, k, w)
    assert not dominance_proved(robot, k, 100.0 * w)
    big = 60.0 * w  # 9 of these 60 poses are not dominant: numpy.linalg.solve for them
    q = random_poses(robot, 60, seed=2)
    got = pose_metrics(robot, q, k, big, LENGTH, threads=1)
    assert_same(got, reference(robot, q, k, big, LENGTH), rtol=1e-12)


def test_empty_and_single_pose():
    robot = load_robot("kr240-2")
    k, w = robot.nominal_stiffness, WORST_CASE_WRENCH
    empty = pose_metrics(robot, np.zeros((0, 6)), k, w, LENGTH, threads=1)
    assert empty["v_p"].shape == (0,) and empty["deflection"].shape == (0, 6)
    q = np.radians([0.0, -30, 20, 45, 45, 45])
    one = pose_metrics(robot, q, k, w, LENGTH, threads=1)
    assert one["v_p"].shape == ()
    assert_same({key: np.asarray(v)[None] for key, v in one.items()},
                reference(robot, q[None], k, w, LENGTH))
