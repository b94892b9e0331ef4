"""Coverage on a second robot the project ships no model of: the Unitree Z1 URDF.

The study's own arm (``_own_robot.py``) is a DH industrial arm; the Z1
(:mod:`tests.studies._z1`, from example-robot-data) has other axes, a URDF tool frame
and a hundred times smaller stiffness and loads. Measured (2000 campaigns per cell,
binomial sd 0.49 %, ``python -m tests.studies.coverage_study --robot z1 --trials 2000
--seed 7``): 93.6-96.3 % for ols, wls and exact at the nominal loads and twice them.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.studies import _z1
from tests.studies._coverage import campaign_setup, coverage


@pytest.fixture(scope="module")
def z1(tmp_path_factory):
    if not _z1.URDF.is_file():
        pytest.skip(f"example-robot-data not installed (no {_z1.URDF})")
    return campaign_setup(_z1.write_protocol(tmp_path_factory.mktemp("z1")))


@pytest.mark.parametrize("method", ["ols"])
def test_z1_coverage_quick(z1, method):
    """300 campaigns (binomial sd 1.26 %): 95 +- 4 % per joint at twice the loads, where
    the linearisation matters most (ols: its bias corrected); the other methods and
    loads in the slow test."""
    robot, q, W, k = z1
    assert robot.n == 6 and len(q) == 5 and len(W) == 3
    cov, given = coverage(robot, q, W, k, method, 2.0, 300, seed=5)
    assert given == 300
    assert np.all(np.abs(cov - 0.95) <= 0.04), cov


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1.0, 2.0])
@pytest.mark.parametrize("method", ["ols", "wls", "exact"])
def test_z1_coverage_every_method(z1, method, scale):
    robot, q, W, k = z1
    cov, given = coverage(robot, q, W, k, method, scale, 1000, seed=3)
    assert given == 1000
    assert np.all(np.abs(cov - 0.95) <= 0.03), cov
