"""Data that cannot identify the joints: clear refusals naming the line, column or joint."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimate import identify, parse_joints
from analysis.identification.poses import count_poses, pose_groups, pose_tolerance

from ._sim import simulate


def test_fewer_equations_than_unknowns(kr240, zone_poses, w_eff):
    tests = simulate(kr240, zone_poses[:1], w_eff, kr240.nominal_stiffness, rotations=False)
    with pytest.raises(InputError, match="3 measured displacement components for 6 unknown"):
        identify(kr240, tests, joints=range(6))


def test_all_tests_at_one_pose(kr240, zone_poses):
    q = np.repeat(zone_poses[:1], 3, axis=0)
    w = np.array([[0, 2200, 0, 0, 0, 0], [0, 0, 2200, 0, 0, 0], [0, 0, 0, 200, 200, 0.0]])
    tests = simulate(kr240, q, w, kr240.nominal_stiffness)
    with pytest.raises(InputError, match=r"all 3 tests \(lines 2..4, columns q1_deg..q6_deg\) "
                                         r"are at one pose"):
        identify(kr240, tests)


def test_one_pose_with_encoder_jitter_is_still_one_pose(kr240, zone_poses):
    """15 tests at one pose read with 0.0003 deg of jitter (distinct labels): one pose."""
    rng = np.random.default_rng(4)
    q = np.repeat(zone_poses[:1], 15, axis=0) + np.radians(3e-4) * rng.normal(size=(15, 6))
    w = np.tile([[0, 2200, 0, 0, 0, 0], [0, 0, 2200, 0, 0, 0], [0, 0, 0, 200, 200, 0.0]], (5, 1))
    tests = simulate(kr240, q, w, kr240.nominal_stiffness)
    assert len(set(tests.pose)) == 15
    assert len(np.unique(np.round(tests.q, 9), axis=0)) == 15  # what rounding used to count
    with pytest.raises(InputError, match=r"all 15 tests .* are at one pose"):
        identify(kr240, tests)


def test_poses_counted_within_the_encoder_noise(kr240, zone_poses, w_eff):
    """5 poses x 3 jittered readings -> 5 poses (and the report's n_poses says so)."""
    rng = np.random.default_rng(5)
    q = np.repeat(zone_poses[:5], 3, axis=0) + np.radians(3e-4) * rng.normal(size=(15, 6))
    tests = simulate(kr240, q, w_eff, kr240.nominal_stiffness)
    assert count_poses(tests.q, pose_tolerance()) == 5
    groups = pose_groups(tests.q, pose_tolerance())
    np.testing.assert_array_equal(groups, np.repeat(np.arange(5), 3))
    assert identify(kr240, tests, validate=False).n_poses == 5


def test_zero_wrench_row(kr240, zone_poses, w_eff):
    tests = simulate(kr240, zone_poses[:3], w_eff, kr240.nominal_stiffness)
    tests.w[1] = 0.0
    with pytest.raises(InputError, match=r"line 3, columns fx_N, fy_N, fz_N, mx_Nm, my_Nm, "
                                         r"mz_Nm: zero wrench"):
        identify(kr240, tests)


def test_nan_in_arrays_names_line_and_column(kr240, zone_poses, w_eff):
    tests = simulate(kr240, zone_poses[:3], w_eff, kr240.nominal_stiffness)
    tests.q[2, 3] = np.nan
    with pytest.raises(InputError, match=r"line 4, column q4_deg: joint angles must be finite"):
        identify(kr240, tests)


def test_joint_angle_outside_limits(kr240, zone_poses, w_eff):
    tests = simulate(kr240, zone_poses[:3], w_eff, kr240.nominal_stiffness)
    tests.q[0, 1] = np.radians(-30.0)  # theta2 limits 0..146 deg
    with pytest.raises(InputError, match=r"line 2, column q2_deg: -30.000 deg is outside"):
        identify(kr240, tests)


def test_joint_without_torque_is_named(kr240, zone_poses, w_eff):
    """A pure z force gives no torque about the vertical axis 1: its column of A is zero."""
    tests = simulate(kr240, zone_poses[:4], np.array([0, 0, 2000.0, 0, 0, 0]),
                     kr240.nominal_stiffness)
    with pytest.raises(InputError, match=r"--joints: joint 1 cannot be identified: no test "):
        identify(kr240, tests)


def test_rank_deficient_wrist_is_named(kr240, zone_poses, w_eff):
    """theta5 = 0 at every pose: axes 4 and 6 coincide and their columns are parallel."""
    q = zone_poses[:5].copy()
    q[:, 4] = 0.0
    tests = simulate(kr240, q, w_eff, kr240.nominal_stiffness)
    with pytest.raises(InputError, match=r"joint [46] cannot be identified from these tests: the "
                                         r"condition number of the column-scaled A"):
        identify(kr240, tests)
    # taking joint 6 as rigid makes the rest identifiable
    res = identify(kr240, tests, "exact", joints=(0, 1, 2, 3, 4), validate=False)
    assert np.all(np.isfinite(res.k[:5]))


def test_bad_method_and_joint_lists(kr240, zone_poses, w_eff):
    tests = simulate(kr240, zone_poses[:3], w_eff, kr240.nominal_stiffness)
    with pytest.raises(InputError, match="--method: unknown method 'lsq'"):
        identify(kr240, tests, "lsq")
    with pytest.raises(InputError, match="--joints: joint 7 is out of range"):
        parse_joints("1,7")
    with pytest.raises(InputError, match="--joints: 'x' is not a joint number"):
        parse_joints("1,x")
    with pytest.raises(InputError, match="--joints: list each joint once"):
        parse_joints("1,1")
    assert parse_joints("3, 1,2") == (0, 1, 2)


def test_translational_misfit_names_the_rigid_wrist_first(kr240, zone_poses, w_eff):
    """Translations only: joints 1-3 are identified and the wrist taken as rigid. Under
    w_eff's 200 N m moments the real wrist (Table 2 stiffness) turns the flange by ~0.5 mrad,
    moving P through the wrist offsets far beyond the tracker noise: the chi-square refuses
    (a wrong k1..k3 is worse than an error), and the first cause named is that rigid wrist,
    with the way out; the same campaign of a robot whose wrist is rigid is not refused."""
    from analysis.identification.checks.plausibility import problems
    from analysis.identification.noise import NoiseModel

    noise = NoiseModel(translation_sigma_override=30e-6, rotation_sigma_override=40e-6)
    tests = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, noise=noise,
                     rotations=False)
    res = identify(kr240, tests, noise=noise, validate=False)
    assert res.joints == (0, 1, 2)
    misfit = [p for p in problems(res, None) if p.startswith("misfit")]
    assert len(misfit) == 1 and res.chi2_reduced > 3
    assert "(1) the wrist joints 4-6 taken as rigid" in misfit[0]
    assert "--joints 1,2,3,4,5" in misfit[0]
    rigid = np.array(kr240.nominal_stiffness, dtype=float)
    rigid[3:] *= 1e6
    tests = simulate(kr240, zone_poses, w_eff, rigid, noise=noise, rotations=False)
    res = identify(kr240, tests, noise=noise, validate=False)
    assert not any(p.startswith("misfit") for p in problems(res, None)), res.chi2_reduced


def test_unreliable_linear_correction_is_named_first(kr240, zone_poses, w_eff):
    """At 70 x w_eff (~220 kN: past any real load, where the linearisation of ols is
    so poor that its bias moves by 0.53 se per se of x, beyond the 0.5 limit) the raw
    linear fit is kept and refused (at 45 x, once refused for 6 steps not being enough,
    the correction converges in 8 steps to within 1 se of the truth). Its residuals are
    the linear model's, so the chi-square is huge (~1e7); the first problem named is the
    linearisation with its way out (--method exact), and the misfit's first cause is the
    linear model, not the tool point. The exact fit of the same data is not refused and
    recovers the truth."""
    from analysis.identification.checks.plausibility import problems
    from analysis.identification.noise import NoiseModel

    noise = NoiseModel(translation_sigma_override=30e-6, rotation_sigma_override=20e-6)
    w = np.array([w_eff, w_eff * [1, -1, 1, -1, 1, 1], w_eff[[1, 0, 2, 4, 3, 5]]]) * 70.0
    q = np.repeat(zone_poses[:6], 3, axis=0)
    tests = simulate(kr240, q, np.tile(w, (6, 1)), kr240.nominal_stiffness, noise=noise)
    res = identify(kr240, tests, method="ols", noise=noise, validate=False)
    assert not res.linear_bias["reliable"]
    found = problems(res, None)
    assert found[0].startswith("linearisation bias") and "--method exact" in found[0]
    misfit = [p for p in found if p.startswith("misfit")]
    assert misfit and "(1) the linear model of ols at these loads" in misfit[0], found
    exact = identify(kr240, tests, method="exact", noise=noise, validate=False)
    assert not problems(exact, None)
    z = (exact.k - kr240.nominal_stiffness) / exact.se_k
    assert np.all(np.abs(z) < 4), z


def test_missing_held_out_check_is_said(kr240, zone_poses, w_eff):
    """The held-out check needs 3 folds; with fewer (2 poses here) the result says that it
    was not made, instead of leaving the validation out silently."""
    tests = simulate(kr240, zone_poses[:2], w_eff, kr240.nominal_stiffness)
    res = identify(kr240, tests, validate=True)
    assert res.validation is None
    said = [w for w in res.warnings if w.startswith("no held-out validation")]
    assert len(said) == 1 and "2 fold(s)" in said[0] and "2 poses" in said[0], res.warnings
    res = identify(kr240, simulate(kr240, zone_poses[:3], w_eff, kr240.nominal_stiffness),
                   validate=True)
    assert res.validation is not None and len(res.validation) == 3
    assert not any(w.startswith("no held-out validation") for w in res.warnings)
