"""Simulated campaigns for the identification tests (nonlinear equilibrium data)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.studies.robustness import W_EFF, sample_poses
from analysis.model.robots import load_robot


@pytest.fixture(scope="session")
def kr240():
    return load_robot("kr240-2")


@pytest.fixture(scope="session")
def zone_poses(kr240):
    """12 poses from the KR240-2's good zones, 1/kappa_F >= 0.3 (seeded)."""
    return sample_poses(kr240, 12, np.random.default_rng(7), min_inverse_condition=0.3)


@pytest.fixture(scope="session")
def w_eff():
    return W_EFF.copy()
