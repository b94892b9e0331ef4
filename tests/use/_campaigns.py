"""Many simulated campaigns of the KR240-2 at once, for the statistical tests.

The design is that of the demo protocol (5 poses in the paper's zones, eq. 22
loads, 3 repeats): displacements from the nonlinear equilibrium at the true
stiffness plus normal noise of the protocol's sigmas (30 um, 20 urad per
reading, sqrt(1.5) for a loaded-minus-unloaded displacement; 0.5 N, 0.05 N m),
identified by the batched exact fit (Gauss-Newton) with its covariance.
"""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.gauss_newton import gauss_newton
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw
from tests.report import report_runs

# the demo design: the same five poses and load cases as the report tests' simulated runs
TRUE_K = report_runs.TRUE_K
POSES_DEG = report_runs.POSES_DEG
WRENCHES = np.array([report_runs.WRENCH[name] for name in report_runs.LOADS], dtype=float)
REPEATS = 3
NOISE = NoiseModel(translation_sigma_override=30e-6 * np.sqrt(1.5),
                   rotation_sigma_override=20e-6 * np.sqrt(1.5),
                   force_sigma=0.5, moment_sigma=0.05)


def identify_campaigns(robot, k_true: np.ndarray, trials: int, seed: int):
    """(x (T, 6), cov_x (T, 6, 6)) of ``trials`` independent simulated campaigns."""
    rng = np.random.default_rng(seed)
    q = np.radians(np.repeat(POSES_DEG, REPEATS, axis=0))
    w = np.repeat(WRENCHES, REPEATS, axis=0)
    d = displacement_screw(robot, q, k_true, w)
    m = len(q)
    dn = d + rng.normal(size=(trials, m, 6)) * NOISE.displacement_sigma
    wn = w + rng.normal(size=(trials, m, 6)) * NOISE.wrench_sigma
    qt = np.broadcast_to(q, (trials, m, 6)).copy()
    x0 = np.broadcast_to(1.0 / k_true, (trials, 6)).copy()
    fit = gauss_newton(robot, qt, wn, dn, np.ones(dn.shape, bool), tuple(range(6)), NOISE, x0)
    assert np.all(fit.valid) and np.all(fit.converged)
    return fit.x, fit.cov_x
