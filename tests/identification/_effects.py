"""Campaigns whose truth adds one effect to the joint springs, for the cause tests.

Independent of the analysis' regressors where it matters: the link compliance is a
cantilever beam's (force-moment coupled) compliance in a frame turned from the one the
alternative uses, the lost motion moves the joints inside the nonlinear equilibrium's
displacement, and the compensator changes k2 with q2 in the equilibrium itself.
Gravity torques come from point masses at the joint origins and P (a test mass model).
"""

from __future__ import annotations

import numpy as np

from analysis.identification.checks.cause_columns import link_jacobian
from analysis.identification.io.measurements import TestArrays
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.kinematics import chain_state, jacobian

#: point masses (kg) at the origins of joints 2..6 and at P (a 240 kg-payload arm's order)
MASSES = np.array([0.0, 300.0, 250.0, 120.0, 40.0, 20.0, 60.0])
GRAVITY = np.array([0.0, 0.0, -9.81])

LOADS = np.array([[0.0, 2200.0, 2200.0, 200.0, 200.0, 0.0],
                  [0.0, -2200.0, 2200.0, -200.0, 200.0, 0.0],
                  [2200.0, 0.0, 2200.0, 200.0, -200.0, 0.0]])


def campaign(poses: np.ndarray, loads: np.ndarray = LOADS) -> tuple[np.ndarray, np.ndarray]:
    """(q, w) of every pose with every load (m = poses x loads)."""
    q = np.repeat(poses, len(loads), axis=0)
    w = np.tile(loads, (len(poses), 1))
    return q, w


def gravity_torques(robot, q: np.ndarray) -> np.ndarray:
    """g (m, 6) (N m): the torque about each joint axis of the point masses' weights beyond it."""
    st = chain_state(robot, q)
    pts = np.concatenate([st.origins, st.tip[:, None, :3, 3]], axis=1)  # (m, 7, 3)
    g = np.zeros(q.shape)
    for j in range(6):
        for i in range(j + 1, 7):
            r = pts[:, i] - st.origins[:, j]
            g[:, j] += MASSES[i] * np.einsum("mk,mk->m", np.cross(r, GRAVITY), st.axes[:, j])
    return g


def gear_torques(robot, q: np.ndarray, w: np.ndarray) -> np.ndarray:
    """tau (m, 6) (N m): J^T w plus the weights' torques, each joint's transmitted torque."""
    return np.einsum("mrj,mr->mj", jacobian(robot, q), w) + gravity_torques(robot, q)


def _beam(length: float, ei: float, gj: float, ea: float) -> np.ndarray:
    """6 x 6 compliance of a cantilever along x at its free end [f; m] -> [dp; dr]."""
    c = np.zeros((6, 6))
    c[0, 0] = length / ea
    for f, mo, s in ((1, 5, 1.0), (2, 4, -1.0)):
        c[f, f] = length**3 / (3 * ei)
        c[mo, mo] = length / ei
        c[f, mo] = c[mo, f] = s * length**2 / (2 * ei)
    c[3, 3] = length / gj
    return c


def link_compliances(scale: float) -> dict[int, np.ndarray]:
    """{link: C (6, 6)} of links 2 and 3 (0-based 1, 2): beams turned by 0.3 rad about z
    from the analysis' frame, ``scale`` times a hollow steel box's compliance."""
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    T = np.zeros((6, 6))
    T[:3, :3] = T[3:, 3:] = R
    return {1: scale * T @ _beam(1.15, 2.1e11 * 2.4e-4, 8e10 * 3.0e-4, 2.1e11 * 1.2e-2) @ T.T,
            2: scale * T @ _beam(1.2, 2.1e11 * 1.2e-4, 8e10 * 1.5e-4, 2.1e11 * 8e-3) @ T.T}


def true_displacement(robot, q, w, k, links=None, band=None, compensator=0.0):
    """(m, 6) displacement of P, loaded minus unloaded reference: the joint springs' exact
    equilibrium (k2 scaled by 1 + compensator (q2 - mid)/half-range), plus J_l C_l J_l^T w
    of each link in ``links``, plus J[:, j] band_j for joints whose gear torque flips sign
    (``band`` (6,) dead bands 2b, rad)."""
    q = np.asarray(q, dtype=float)
    kk = np.broadcast_to(np.asarray(k, float), q.shape).copy()
    if compensator:
        lo, hi = np.min(q[:, 1]), np.max(q[:, 1])
        t = (q[:, 1] - (lo + hi) / 2) / max((hi - lo) / 2, 1e-9)
        kk[:, 1] *= 1.0 + compensator * t
    d = displacement_screw(robot, q, kk, w)
    if links:
        st = chain_state(robot, q)
        for link, C in links.items():
            Jl = link_jacobian(st.origins, st.axes, st.tip, link)
            d += np.einsum("mra,ab,msb,ms->mr", Jl, C, Jl, w)
    if band is not None:
        t_ref, t_load = gravity_torques(robot, q), gear_torques(robot, q, w)
        step = (np.sign(t_load) - np.sign(t_ref)) / 2
        d += np.einsum("mrj,mj->mr", jacobian(robot, q), step * band)
    return d


def measured(q, w, d, noise: NoiseModel, seed: int) -> TestArrays:
    """The tests as measured: instrument noise on d, w and q (seeded)."""
    rng = np.random.default_rng(seed)
    d = d + rng.normal(size=d.shape) * noise.displacement_sigma
    wm = w + rng.normal(size=w.shape) * noise.wrench_sigma
    qm = q + rng.normal(size=q.shape) * noise.joint_sigma
    m = q.shape[0]
    return TestArrays(pose=np.array([f"P{i // 3 + 1}" for i in range(m)]), q=qm, w=wm, d=d,
                      measured=np.ones((m, 6), bool), line=np.arange(m) + 2)
