"""Frame transforms, the rigid fit and the safety helpers, against hand computations."""

from __future__ import annotations

import numpy as np
import pytest

from drivers import frames, safety
from drivers.errors import DeviceFault, SafetyRefusal


def test_wrench_to_base_matches_hand_computation():
    # Flange at (1, 0, 2), rotated +90 deg about z; sensor 0.1 m along flange z.
    flange = np.eye(4)
    flange[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    flange[:3, 3] = [1.0, 0.0, 2.0]
    mount = np.eye(4)
    mount[:3, 3] = [0.0, 0.0, 0.1]
    # Sensor reads 10 N along its x (= base y), and 1 N m about its z (= base z).
    w_s = np.array([10.0, 0, 0, 0, 0, 1.0])
    p = np.array([1.0, 0.0, 2.3])  # tool point 0.2 m beyond the sensor origin (1, 0, 2.1)
    w = frames.wrench_to_base(w_s, flange, mount, p)
    # f_b = (0, 10, 0). m_P = m_o + (o - P) x f = (0,0,1) + (0,0,-0.2) x (0,10,0) = (2, 0, 1).
    np.testing.assert_allclose(w, [0, 10, 0, 2.0, 0, 1.0], atol=1e-12)


def test_wrench_to_base_is_batched_and_rejects_bad_transforms():
    w = frames.wrench_to_base(np.ones((4, 6)), np.eye(4), np.eye(4), np.zeros(3))
    assert w.shape == (4, 6)
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match="orthonormal"):
        frames.wrench_to_base(np.ones(6), bad, np.eye(4), np.zeros(3))


def test_fit_rigid_recovers_transform_and_residual():
    rng = np.random.default_rng(3)
    R = frames.rotvec_to_matrix([0.3, -0.2, 1.1])
    t = np.array([1.0, -2.0, 0.5])
    model = np.array([[0.1, 0, 0], [0, 0.1, 0], [0, 0, 0.1], [0.05, 0.05, 0]])
    meas = model @ R.T + t
    T, rms = frames.fit_rigid(model, meas)
    np.testing.assert_allclose(T[:3, :3], R, atol=1e-12)
    np.testing.assert_allclose(T[:3, 3], t, atol=1e-12)
    assert rms < 1e-12
    noisy = meas + rng.normal(0, 1e-4, meas.shape)
    _, rms = frames.fit_rigid(model, noisy)
    assert 1e-5 < rms < 3e-4


def test_fit_rigid_refuses_collinear_reflectors():
    line = np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0.0]])
    with pytest.raises(DeviceFault, match="collinear"):
        frames.fit_rigid(line, line)


@pytest.mark.parametrize("rv", [[0, 0, 0], [0.1, 0.2, -0.3], [0, 0, np.pi - 1e-9], [3.0, 0, 0]])
def test_rotation_conversions_round_trip(rv):
    R = frames.rotvec_to_matrix(rv)
    np.testing.assert_allclose(frames.rotvec_to_matrix(frames.matrix_to_rotvec(R)), R,
                               atol=1e-7)
    np.testing.assert_allclose(frames.quat_to_matrix(frames.matrix_to_quat(R)), R, atol=1e-7)


def test_joint_limit_check_names_the_offender_in_degrees():
    lo, hi = np.full(6, -np.pi), np.full(6, np.pi)
    ok = np.zeros((2, 6))
    assert safety.check_joint_targets(ok, lo, hi).shape == (2, 6)
    bad = ok.copy()
    bad[1, 2] = np.deg2rad(178.0)
    with pytest.raises(SafetyRefusal, match=r"pose 2, joint 3: target 178.00 deg outside "
                                            r"\[-175.00, 175.00\]"):
        safety.check_joint_targets(bad, lo, hi, margin=np.deg2rad(5))
    with pytest.raises(SafetyRefusal, match="NaN"):
        safety.check_joint_targets(np.full(6, np.nan), lo, hi)


def test_cap_motion_and_force_limit():
    assert safety.cap_motion(2.0, 0.5, 1.0, 1.0) == (1.0, 0.5)
    with pytest.raises(SafetyRefusal):
        safety.cap_motion(0.0, 1.0, 1.0, 1.0)
    safety.check_force([300, 400, 0, 0, 0, 0], max_force=500.0)  # |f| = 500: allowed
    with pytest.raises(SafetyRefusal, match="force 500.1 N above"):
        safety.check_force([300.06, 400.06, 0, 0, 0, 0], max_force=500.0)
    with pytest.raises(SafetyRefusal, match="moment"):
        safety.check_force([0, 0, 0, 0, 0, 60], max_force=500.0, max_moment=50.0)


def test_dry_run_listing_and_confirmation():
    text = safety.format_motion_list(np.deg2rad([[10, -90, 90, 0, 45, 0]]), speed=0.5)
    assert "28.6 deg/s" in text and "-90.000" in text and "45.000" in text
    # a target a hair below zero (round-off of a conversion) is listed as 0.000, not -0.000
    tiny = safety.format_motion_list(np.array([[-1e-12, -2e-6, 0, 0, 0, 0]]))
    assert "-0.000" not in tiny and tiny.splitlines()[-1].split()[1:3] == ["0.000", "0.000"]
    said = []
    safety.require_confirmation(text, ask=lambda _: "yes", say=said.append)
    assert said == [text]
    with pytest.raises(SafetyRefusal, match="not confirmed"):
        safety.require_confirmation(text, ask=lambda _: "y", say=lambda _: None)
    safety.require_confirmation(text, assume_yes=True, ask=lambda _: 1 / 0, say=lambda _: None)
