"""A tests CSV of N simulated stiffness tests, for the large-import benchmark.

KR240-2 with its nominal stiffness, poses drawn in its zones, ``per_pose``
tests per pose (load cases: forces of 1-2.5 kN and moments of 100-300 N m in
random directions), displacements from the exact equilibrium plus the default
noise model's noise (joint angles, wrench, displacement).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from analysis.identification.io.columns import CSV_COLUMNS
from analysis.identification.noise import NoiseModel
from analysis.identification.studies.robustness import sample_poses
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.robots import load_robot


class Draws(NamedTuple):
    """The random part of a simulated campaign, drawn in this order from one generator."""

    index: np.ndarray        #: (n,) pose of each test (row of ``poses``)
    poses: np.ndarray        #: (P, 6) true joint angles, rad
    wrench: np.ndarray       #: (n, 6) true wrench, N and N m
    e_d: np.ndarray          #: (n, 6) displacement noise, m and rad
    e_w: np.ndarray          #: (n, 6) wrench noise, N and N m
    e_q: np.ndarray          #: (n, 6) encoder noise, rad


def simulated_draws(robot, n: int, per_pose: int = 10, seed: int = 0,
                    noise: NoiseModel | None = None) -> Draws:
    """Poses, loads and noise of :func:`simulated_tests`: the same numbers for the same
    (n, per_pose, seed), whatever the noise figures (a zero figure gives zero noise)."""
    rng = np.random.default_rng(seed)
    n_poses = max(3, -(-n // per_pose))
    qp = sample_poses(robot, n_poses, rng)
    idx = np.repeat(np.arange(n_poses), per_pose)[:n]
    f = rng.normal(size=(n, 3))
    f *= rng.uniform(1000, 2500, (n, 1)) / np.linalg.norm(f, axis=1, keepdims=True)
    mo = rng.normal(size=(n, 3))
    mo *= rng.uniform(100, 300, (n, 1)) / np.linalg.norm(mo, axis=1, keepdims=True)
    noise = NoiseModel() if noise is None else noise
    e_d = rng.normal(size=(n, 6)) * noise.displacement_sigma
    e_w = rng.normal(size=(n, 6)) * noise.wrench_sigma
    e_q = rng.normal(size=(n, 6)) * noise.joint_sigma
    return Draws(idx, qp, np.hstack([f, mo]), e_d, e_w, e_q)


def simulated_tests(n: int, per_pose: int = 10, seed: int = 0, noise: NoiseModel | None = None):
    """(pose labels, q rad, w N/N m, d m/rad) of n tests (noisy, as measured).

    ``noise``: the instruments' figures the readings are drawn with (default
    :class:`NoiseModel()`); a zero figure leaves that reading exact and the other draws
    unchanged (the same random numbers are drawn whatever the figures).
    """
    robot = load_robot("kr240-2")
    dr = simulated_draws(robot, n, per_pose, seed, noise)
    q, w = dr.poses[dr.index], dr.wrench
    d = np.empty((n, 6))
    for s in range(0, n, 50_000):
        sl = slice(s, min(n, s + 50_000))
        d[sl] = displacement_screw(robot, q[sl], robot.nominal_stiffness, w[sl])
    labels = np.char.add("P", (dr.index + 1).astype(str))
    return labels, q + dr.e_q, w + dr.e_w, d + dr.e_d


def write_csv(path: Path, n: int, per_pose: int = 10, seed: int = 0) -> None:
    """Write n simulated tests in the public CSV format (deg, N, N m, mm, mrad)."""
    labels, q, w, d = simulated_tests(n, per_pose, seed)
    values = np.hstack([np.degrees(q), w, 1e3 * d])
    with open(path, "w") as fh:
        fh.write(",".join(CSV_COLUMNS) + "\n")
        body = np.column_stack([labels, np.char.mod("%.10g", values)])
        fh.write("\n".join(",".join(row) for row in body.tolist()))
        fh.write("\n")
