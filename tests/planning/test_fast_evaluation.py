"""Blocked candidate evaluation and the Gram-matrix information identity, against the
per-candidate reference computations."""

from __future__ import annotations

import numpy as np

import analysis.kinetostatics.maps as maps
from analysis.kinetostatics.dexterity import inverse_condition, normalized_jacobian
from analysis.kinetostatics.stiffness import kc_influence
from analysis.model.kinematics import jacobian
from campaign.planning.candidates import evaluate, sample
from campaign.planning.design import information, information_of_tests, scaled_blocks
from campaign.protocol_robot import (
    characteristic_length,
    prior_stiffness,
    protocol_robot,
    sampling_boxes,
)


def test_information_identity_matches_blocks(kr_protocol):
    rng = np.random.default_rng(5)
    robot = protocol_robot(kr_protocol)
    J = jacobian(robot, rng.uniform(-2, 2, (50, 6)))
    wrenches = kr_protocol.wrenches()
    sigma, k = kr_protocol.measurement_sigma(), robot.nominal_stiffness
    case = rng.integers(0, len(wrenches), 50)
    one = information_of_tests(J, wrenches[case][:, None, :], sigma, k, block=7)
    ref = information(scaled_blocks(J, wrenches[case], sigma, k))
    np.testing.assert_allclose(one, ref, rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    every = information_of_tests(J, np.broadcast_to(wrenches, (50, *wrenches.shape)), sigma, k)
    ref_all = sum(information(scaled_blocks(J, w, sigma, k)) for w in wrenches)
    np.testing.assert_allclose(every, ref_all, rtol=1e-12, atol=1e-12 * np.abs(ref_all).max())


def test_blocked_evaluation_matches_per_candidate(kr_protocol, monkeypatch):
    import campaign.planning.candidates as candidates

    monkeypatch.setattr(candidates, "BLOCK", 37)  # several blocks, one ragged
    assert maps.BLOCK != 37
    robot = protocol_robot(kr_protocol)
    k = prior_stiffness(kr_protocol, robot)
    q, zone = sample(sampling_boxes(kr_protocol, robot), 200, seed=3)
    L = characteristic_length(kr_protocol, robot)
    cand = evaluate(kr_protocol, robot, q, zone, k, L)
    J = jacobian(robot, q)
    np.testing.assert_allclose(cand.J, J, rtol=0, atol=1e-14)
    inv_k = inverse_condition(normalized_jacobian(J, L))
    np.testing.assert_allclose(cand.inv_kappa, inv_k, rtol=1e-10)
    rows = np.flatnonzero(np.isfinite(cand.v_p[:, 0]))
    assert rows.size > 50
    for c, w in enumerate(kr_protocol.wrenches()):
        v_p, v_r = kc_influence(robot, q[rows], k, w)
        np.testing.assert_allclose(cand.v_p[rows, c], v_p, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(cand.v_r[rows, c], v_r, rtol=1e-9, atol=1e-15)


def test_tests_information_equals_the_gathered_batch(kr_protocol, monkeypatch):
    """Gathering J per block and sharing C per pose changes no bit of the information."""
    import campaign.planning.criteria as criteria
    from campaign.run_noise import noise_from_protocol

    monkeypatch.setattr(criteria, "BLOCK", 29)  # several blocks, one ragged
    rng = np.random.default_rng(11)
    robot = protocol_robot(kr_protocol)
    J = jacobian(robot, rng.uniform(-2, 2, (40, 6)))
    wrenches, k = kr_protocol.wrenches(), robot.nominal_stiffness
    noise = noise_from_protocol(kr_protocol)
    pose = np.sort(rng.integers(0, 40, 100))
    case = rng.integers(0, len(wrenches), 100)
    ref = criteria.candidate_information(J[pose], wrenches[case], noise, k, 3)
    got = criteria.tests_information(J, pose, wrenches, case, noise, k, 3)
    assert np.array_equal(got, ref) and np.abs(ref).max() > 0
    C = criteria.pose_compliance(J, k)
    for w in wrenches:  # one wrench for every test (the "all" selection)
        ref = criteria.candidate_information(J[pose], w, noise, k, 2)
        assert np.array_equal(criteria.tests_information(J, pose, w, None, noise, k, 2, C), ref)


def test_random_design_with_given_zones_and_separation_distance():
    from campaign.planning.design import random_design, zones_of
    from campaign.planning.separation import Separation

    rng = np.random.default_rng(2)
    q = rng.uniform(-1, 1, (3000, 6))
    group, zone = np.repeat(np.arange(1500), 2), np.repeat(rng.integers(0, 4, 1500), 2)
    sep = Separation(q, group, 0.3)
    assert np.array_equal(zones_of(zone), np.unique(zone))
    for seed in range(5):
        assert np.array_equal(random_design(group, zone, 6, seed, sep, zones_of(zone)),
                              random_design(group, zone, 6, seed, sep))
    for c in (0, 17, 2999):  # bit-equal to the row reduction it replaces
        assert np.array_equal(sep._distance2(c), np.sum((q - q[c]) ** 2, axis=1))
