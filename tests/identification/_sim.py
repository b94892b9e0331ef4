"""Simulated tests from the nonlinear equilibrium, for the identification tests."""

from __future__ import annotations

import numpy as np

from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw


def simulate(robot, q, w, k, noise: NoiseModel | None = None, seed: int = 0,
             rotations: bool = True) -> TestArrays:
    """Tests whose displacement is the exact equilibrium's, plus optional instrument noise.

    The wrench is applied exactly; the measured wrench, joint angles and
    displacement carry the noise model's normal noise.
    """
    q = np.atleast_2d(q)
    w = np.broadcast_to(np.asarray(w, float), q.shape[:-1] + (6,)).copy()
    d = displacement_screw(robot, q, k, w)
    qm, wm = q.copy(), w.copy()
    if noise is not None:
        rng = np.random.default_rng(seed)
        d = d + rng.normal(size=d.shape) * noise.displacement_sigma
        wm = w + rng.normal(size=w.shape) * noise.wrench_sigma
        qm = q + rng.normal(size=q.shape) * noise.joint_sigma
    if not rotations:
        d[:, 3:] = np.nan
    m = q.shape[0]
    return TestArrays(
        pose=np.array([f"P{i + 1}" for i in range(m)]), q=qm, w=wm, d=d,
        measured=np.isfinite(d), line=np.arange(m) + 2,
    )
