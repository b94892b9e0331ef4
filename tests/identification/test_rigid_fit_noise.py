"""The reflector rigid-fit noise formula against a Monte-Carlo of the drivers' rigid fit."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.noise import rigid_fit_sigma
from drivers.frames import fit_rigid, matrix_to_rotvec

REFLECTORS = np.array([[0, 0, 0], [0.12, 0, -0.05], [0, 0.12, -0.05], [-0.08, -0.08, -0.02]])


def test_rigid_fit_sigma_matches_monte_carlo():
    sigma = 20e-6
    s_t, s_r = rigid_fit_sigma(REFLECTORS, sigma)
    rng = np.random.default_rng(1)
    rot, pos = [], []
    for _ in range(3000):
        measured = REFLECTORS + rng.normal(0, sigma, REFLECTORS.shape)
        T, _ = fit_rigid(REFLECTORS, measured)
        rot.append(matrix_to_rotvec(T[:3, :3]))
        pos.append(T[:3, 3])
    mc_r = np.std(rot, axis=0).max()
    mc_t = np.std(pos, axis=0).max()
    assert mc_r == pytest.approx(s_r, rel=0.08)
    assert mc_t == pytest.approx(s_t, rel=0.08)
    # a 100 mm-scale triangle turns 20 um into a few hundred urad
    assert 1e-4 < s_r < 5e-4


def test_collinear_reflectors_refused():
    with pytest.raises(ValueError, match="collinear"):
        rigid_fit_sigma(np.array([[0, 0, 0], [0.1, 0, 0], [0.2, 0, 0]]), 1e-5)
