"""The batched leave-one-pose-out (ols: QR downdate; exact: warm start) equals the
reference path that refits every fold from scratch."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.noise import NoiseModel
from analysis.identification.validation.crossval import leave_one_pose_out

from ._sim import simulate

COLS = ["rms_translation_m", "rms_rotation_rad", "rms_normalized"]
#: the check against the prediction's total uncertainty: the batched paths take the
#: folds' covariances from the full-data factorisation (the noise covariances at the
#: held-out folds' estimates, which move by ~se/x), the refits their own: measured
#: 5e-4 relative on the statistic (OLS, 12 poses), 5e-3 on a p-value of 0.005
TOTAL = ["rms_normalized_total", "limit_normalized_total"]


def _tests(kr240, zone_poses, w_eff, repeat_labels=False, rotations=True):
    noise = NoiseModel()
    tests = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, noise=noise, seed=4,
                     rotations=rotations)
    if repeat_labels:  # two tests per pose label: folds remove both
        tests.pose[:] = [f"P{i // 2}" for i in range(tests.m)]
    return tests, noise


@pytest.mark.parametrize("repeat_labels, rotations", [(False, True), (True, True),
                                                      (False, False)])
def test_ols_batched_equals_refits(kr240, zone_poses, w_eff, repeat_labels, rotations):
    tests, noise = _tests(kr240, zone_poses, w_eff, repeat_labels, rotations)
    joints = (0, 1, 2, 3, 4, 5) if rotations else (0, 1, 2)
    fast = leave_one_pose_out(kr240, tests, "ols", joints, noise)
    ref = leave_one_pose_out(kr240, tests, "ols", joints, noise, batched=False)
    assert list(fast["held_out_pose"]) == list(ref["held_out_pose"])
    assert list(fast["note"] == "") == list(ref["note"] == "")
    assert (fast["note"] == "").sum() >= 3
    # QR downdate vs fresh QR per fold: agreement to ~1e-10 relative (cond of A ~1e3)
    np.testing.assert_allclose(fast[COLS].to_numpy(float), ref[COLS].to_numpy(float),
                               rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(fast[TOTAL].to_numpy(float), ref[TOTAL].to_numpy(float),
                               rtol=2e-3, atol=1e-12)
    np.testing.assert_allclose(fast["p_value_total"], ref["p_value_total"], rtol=2e-2,
                               atol=1e-4)
    assert list(fast["beyond_limit"]) == list(ref["beyond_limit"])


def test_exact_warm_start_equals_refits(kr240, zone_poses, w_eff):
    tests, noise = _tests(kr240, zone_poses[:8], w_eff)
    joints = (0, 1, 2, 3, 4, 5)
    fast = leave_one_pose_out(kr240, tests, "exact", joints, noise)
    ref = leave_one_pose_out(kr240, tests, "exact", joints, noise, batched=False)
    # both stop on the Gauss-Newton tolerance (1e-9 relative step) from different starts
    np.testing.assert_allclose(fast[COLS].to_numpy(float), ref[COLS].to_numpy(float),
                               rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(fast[TOTAL].to_numpy(float), ref[TOTAL].to_numpy(float),
                               rtol=1e-6, atol=1e-12)


def test_exact_one_step_is_close_to_refits(kr240, zone_poses):
    """Many poses: one Gauss-Newton step per fold from the full-data estimate instead of
    a refit. The step is exact for the linearised, fixed-weight cost; the refit also
    follows the curvature and re-evaluates the weights at the fold's estimate. With 12
    poses x 3 load cases the held-out errors agree to 1.2e-4 relative (asserted 1e-3;
    8 single-test poses give 3e-3: the fewer tests per fold, the larger its step)."""
    q = np.repeat(zone_poses[:12], 3, axis=0)
    w = np.tile([[0, 2200, 0, 0, 0, 0], [0, 0, 2200, 0, 0, 0], [0, 0, 0, 200, 200, 0.0]],
                (12, 1))
    noise = NoiseModel()
    tests = simulate(kr240, q, w, kr240.nominal_stiffness, noise, seed=4)
    tests.pose[:] = [f"P{i // 3}" for i in range(tests.m)]
    joints = (0, 1, 2, 3, 4, 5)
    step = leave_one_pose_out(kr240, tests, "exact", joints, noise, max_exact_refits=0)
    ref = leave_one_pose_out(kr240, tests, "exact", joints, noise, batched=False)
    assert all("one Gauss-Newton step" in n for n in step["note"])
    assert list(step["n_tests"]) == [3] * 12
    np.testing.assert_allclose(step[COLS].to_numpy(float), ref[COLS].to_numpy(float),
                               rtol=1e-3, atol=1e-15)
    np.testing.assert_allclose(step[TOTAL].to_numpy(float), ref[TOTAL].to_numpy(float),
                               rtol=1e-2, atol=1e-12)


def test_ols_folds_corrected_by_the_full_shift_are_close_to_their_own(kr240, w_eff,
                                                                       monkeypatch):
    """Above EXACT_REFITS_MAX poses the bias-corrected OLS folds are fitted to d less the
    full fit's linearisation error of each test (no model evaluation per fold);
    below, each fold is corrected and predicted by the exact model. 60 poses at w_eff,
    both ways (measured: RMS errors within 1.4e-3 relative, the statistic within 1.8e-3;
    asserted 5e-3)."""
    from analysis.identification.estimate import identify
    from analysis.identification.studies.robustness import sample_poses
    from analysis.identification.validation import crossval

    noise = NoiseModel()
    q = sample_poses(kr240, 60, np.random.default_rng(3), min_inverse_condition=0.3)
    tests = simulate(kr240, q, w_eff, kr240.nominal_stiffness, noise=noise, seed=5)
    shifted = identify(kr240, tests, "ols", noise=noise).validation
    assert all("linearisation error of each test" in n for n in shifted["note"])
    monkeypatch.setattr(crossval, "EXACT_REFITS_MAX", 100)
    own = identify(kr240, tests, "ols", noise=noise).validation
    np.testing.assert_allclose(shifted[COLS].to_numpy(float), own[COLS].to_numpy(float),
                               rtol=5e-3)
    np.testing.assert_allclose(shifted["rms_normalized_total"], own["rms_normalized_total"],
                               rtol=5e-3)


def test_parameter_term_left_out_for_many_folds(kr240, w_eff, monkeypatch):
    """Above PARAMETER_TERM_MAX_POSES folds V = Sigma (the refit's covariance is left
    out): q can only grow (V >= Sigma). Measured on sqrt(q/n), OLS at w_eff, one test per
    pose: at most +22 % with 60 poses (asserted < 25 %), +6 % with 300, +1.6 % (median
    +0.2 %) with 1000, the threshold."""
    from analysis.identification.studies.robustness import sample_poses
    from analysis.identification.validation import downdate

    noise = NoiseModel()
    q = sample_poses(kr240, 60, np.random.default_rng(3), min_inverse_condition=0.3)
    tests = simulate(kr240, q, w_eff, kr240.nominal_stiffness, noise=noise, seed=5)
    joints = tuple(range(6))
    full = leave_one_pose_out(kr240, tests, "ols", joints, noise)
    monkeypatch.setattr(downdate, "PARAMETER_TERM_MAX_POSES", 10)
    noise_only = leave_one_pose_out(kr240, tests, "ols", joints, noise)
    ratio = noise_only["rms_normalized_total"] / full["rms_normalized_total"]
    assert np.all(ratio >= 1 - 1e-9) and np.all(ratio < 1.25), ratio.max()
