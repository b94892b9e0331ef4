"""The tool-point F-test: calibrated under "the tool is right", powerful when P is 100 mm off."""

from __future__ import annotations

import numpy as np

from analysis.identification.checks.tool_check import tool_point_check
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.studies.robustness import sample_poses
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot, with_tool

ROBOT = load_robot("kr240-2")
X = 1.0 / ROBOT.nominal_stiffness
NOISE = NoiseModel()


def _campaign(rng, robot, n_poses=5, per_pose=3) -> TestArrays:
    """Linear-model data (the model of method "ols") of P of ``robot``, with the noise model's
    own residual covariance (displacement noise plus propagated wrench noise)."""
    q = np.repeat(sample_poses(ROBOT, n_poses, rng), per_pose, axis=0)
    f = rng.normal(size=(len(q), 3))
    f *= 2200.0 / np.linalg.norm(f, axis=1, keepdims=True)
    mo = rng.normal(size=(len(q), 3))
    mo *= 300.0 / np.linalg.norm(mo, axis=1, keepdims=True)
    w = np.hstack([f, mo])
    J = jacobian(robot, q)
    d = np.einsum("mrj,j->mr", design_block(J, w), X)
    S = residual_covariance(NOISE, np.einsum("mrj,j,msj->mrs", J, X, J), w)
    d = d + np.einsum("mij,mj->mi", np.linalg.cholesky(S), rng.normal(size=d.shape))
    labels = np.repeat(np.arange(n_poses), per_pose).astype(str)
    return TestArrays(labels, q, w, d, np.ones_like(d, dtype=bool), np.arange(len(q)) + 2)


def test_p_values_are_calibrated_when_the_tool_is_right():
    """400 campaigns measured at the flange and analysed there: P(F >= observed) is uniform,
    so about 5 % fall below 0.05 and (almost) none below the refusal level 1e-3."""
    rng = np.random.default_rng(11)
    p = np.array([tool_point_check(ROBOT, _campaign(rng, ROBOT), range(6), X, NOISE,
                                   "ols").p_value for _ in range(400)])
    # binomial(400, 0.05): mean 20, sd 4.4
    assert 7 <= np.sum(p < 0.05) <= 33
    assert np.sum(p < 1e-3) <= 3
    assert 0.4 < np.median(p) < 0.6


def test_a_tool_point_100_mm_off_is_found_and_located():
    """Measured at P 100 mm along the tool axis, analysed at the flange: refused-level p in
    every campaign, and the offset estimate lands near (0, 0, 100) mm."""
    rng = np.random.default_rng(12)
    tool = with_tool(ROBOT, np.array([0.0, 0.0, 0.1]), np.zeros(3))
    checks = [tool_point_check(ROBOT, _campaign(rng, tool), range(6), X, NOISE, "ols")
              for _ in range(20)]
    assert max(c.p_value for c in checks) < 1e-3
    offsets = np.array([c.offset_m for c in checks])
    assert np.allclose(np.median(offsets, axis=0), [0.0, 0.0, 0.1], atol=0.02)
    # its standard error is honest: the estimates scatter about as it says
    se = np.median([c.se_m for c in checks], axis=0)
    assert np.all(np.std(offsets, axis=0) < 3 * se)


def test_the_test_does_not_depend_on_a_common_noise_scale():
    """F is a ratio: noise figures all 2x too large give the same p-value."""
    rng = np.random.default_rng(13)
    tests = _campaign(rng, ROBOT)
    big = NoiseModel(translation_sigma_override=2 * NOISE.translation_sigma,
                     rotation_sigma_override=2 * NOISE.rotation_sigma,
                     force_sigma=2 * NOISE.force_sigma, moment_sigma=2 * NOISE.moment_sigma)
    a = tool_point_check(ROBOT, tests, range(6), X, NOISE, "ols")
    b = tool_point_check(ROBOT, tests, range(6), X, big, "ols")
    assert np.isclose(a.f_value, b.f_value, rtol=1e-9) and np.isclose(a.p_value, b.p_value)
