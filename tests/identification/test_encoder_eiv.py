"""The bias of the encoder noise in J (analysis/identification/corrections/encoder_eiv.py).

Checked against a seeded Monte-Carlo with the encoder noise inflated 2000-fold (0.01 rad,
so that the bias, ~1e-4 of x, shows against the spread): the mean error of 40 000
least-squares fits of exact linear-model data with A at the noisy joint angles agrees
with b_q within 3 Monte-Carlo standard errors + 15 % on every joint, and is resolved
(> 3 standard errors) on joints 1 and 2. b_q scales as sigma_q^2 (to 1e-6) and is
added to the intervals.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.corrections.encoder_eiv import encoder_bias
from analysis.identification.estimate import identify
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.model.kinematics import jacobian

from ._sim import simulate


def _noise(sigma_q):
    return NoiseModel(translation_sigma_override=20e-6, rotation_sigma_override=20e-6,
                      force_sigma=0.0, moment_sigma=0.0,
                      encoder_resolution=sigma_q * np.sqrt(12))


def test_bias_matches_monte_carlo_with_inflated_encoder_noise(kr240, zone_poses, w_eff):
    q = np.vstack([zone_poses, zone_poses[:3]])  # 15 tests
    m = len(q)
    w = np.tile(w_eff, (m, 1))
    x = 1 / kr240.nominal_stiffness
    sq = 0.01
    tests = TestArrays(np.array([f"P{i}" for i in range(m)]), q, w, np.zeros((m, 6)),
                       np.ones((m, 6), bool), np.arange(m) + 2)
    b = encoder_bias(kr240, tests, tuple(range(6)), x, _noise(sq))
    # equal sigmas and no F/T noise: the weights are uniform, plain least squares
    d = (design_block(jacobian(kr240, q), w) @ x).reshape(-1)
    rng = np.random.default_rng(1)
    errs = []
    for _ in range(20):
        qm = q[None] + rng.normal(size=(2000, m, 6)) * sq
        A = design_block(jacobian(kr240, qm.reshape(-1, 6)), np.tile(w, (2000, 1)))
        A = A.reshape(2000, 6 * m, 6)
        N = np.einsum("tri,trj->tij", A, A)
        errs.append(np.linalg.solve(N, np.einsum("tri,r->ti", A, d)[..., None])[..., 0] - x)
    e = np.concatenate(errs)
    mean, se = e.mean(axis=0), e.std(axis=0) / np.sqrt(len(e))
    assert np.all(np.abs(mean - b) < 3 * se + 0.15 * np.abs(b)), (mean / x, b / x, se / x)
    assert np.all(np.abs(b[:2]) > 3 * se[:2])
    # second order in sigma_q
    b2 = encoder_bias(kr240, tests, tuple(range(6)), x, _noise(2 * sq))
    np.testing.assert_allclose(b2, 4 * b, rtol=1e-6)


def test_bias_is_reported_and_widens_the_interval(kr240, zone_poses, w_eff):
    noise = NoiseModel()
    t = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, noise=noise, seed=2)
    res = identify(kr240, t, "exact", noise=noise, validate=False)
    enc = res.to_dict()["encoder_errors_in_variables"]
    assert enc["added_to_interval"] and enc["tests_used"] == t.m
    rel = np.array(enc["bias_relative"], dtype=float)
    # the default 5 urad encoders: ~1e-10 of x, a vanishing part of a standard error
    assert np.all(rel < 1e-8) and np.all(rel > 0)
    assert max(enc["bias_in_standard_errors"]) < 1e-5
