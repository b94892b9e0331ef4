"""Monte-Carlo of one planned design: the spread of k the identification will see.

A design is a list of tests (pose q, wrench w), each measured ``rows`` times.
Every trial simulates the exact displacement (nonlinear equilibrium at the
true stiffness), adds the noise model's normal noise to every row --
displacement (tracker, reflector fit), wrench (absolute and % of reading),
joint angles (encoders; the measured Jacobian follows to first order, as in
:func:`analysis.identification.studies.robustness.measured_jacobians`) -- and
identifies the compliances by the linear model weighted with each row's
residual covariance at the true compliance (``wls``), by OLS, or by the
batched exact Gauss-Newton fit (``exact``). Batch on the last axis for the
linear kernels of :mod:`analysis.identification.linalg.batch_lsq`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification.estimators.gauss_newton import gauss_newton
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.linalg.batch_lsq import mgs_lstsq
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.studies.robustness import jacobian_derivative
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


@dataclass(frozen=True)
class SimulatedCampaigns:
    """Noisy rows of ``trials`` campaigns (batch first): q (T, m, n) measured joint angles
    (rad), w (T, m, 6) measured wrenches (N, N m), d (T, m, 6) measured displacements
    (m, rad), J (T, m, 6, n) Jacobians at the measured angles; q_true, w_true (m, ...)."""

    q: np.ndarray
    w: np.ndarray
    d: np.ndarray
    J: np.ndarray
    q_true: np.ndarray
    w_true: np.ndarray


def simulate_campaigns(
    robot: RobotModel,
    q: np.ndarray,
    w: np.ndarray,
    k_true: np.ndarray,
    noise: NoiseModel,
    rows: int,
    trials: int,
    rng: np.random.Generator,
) -> SimulatedCampaigns:
    """Draw ``trials`` noisy campaigns of the tests (q (t, n) rad, w (t, 6) N, N m) x ``rows``."""
    q = np.repeat(np.asarray(q, float), rows, axis=0)
    w = np.repeat(np.asarray(w, float), rows, axis=0)
    d = displacement_screw(robot, q, np.asarray(k_true, float), w)
    m, n = q.shape
    J = jacobian(robot, q)
    dJ = jacobian_derivative(robot, q)
    dq = rng.normal(size=(trials, m, n)) * noise.joint_sigma
    wm = w + rng.normal(size=(trials, m, 6)) * noise.wrench_sigma_at(w)
    dm = d + rng.normal(size=(trials, m, 6)) * noise.displacement_sigma
    # J(q + dq) ~ J + dJ . dq, as one (6n x n) @ (n x T) product per test: the einsum
    # summing over k took ~4x longer (a quarter of a GUI slider move at 30 tests)
    Jm = J + np.matmul(dJ.reshape(m, 6 * n, n), dq.transpose(1, 2, 0)).reshape(
        m, 6, n, trials).transpose(3, 0, 1, 2)
    return SimulatedCampaigns(q=q + dq, w=wm, d=dm, J=Jm, q_true=q, w_true=w)


def noise_free_campaign(robot: RobotModel, q: np.ndarray, w: np.ndarray,
                        k_true: np.ndarray) -> SimulatedCampaigns:
    """One campaign (T = 1) of the tests (q (t, n) rad, w (t, 6) N, N m) without noise: the
    exact joint-spring displacements at k_true (N m/rad). A linear estimator's compliances
    from it minus 1/k_true are its linearisation bias at these tests
    (:mod:`analysis.identification.corrections.linear_bias`: ``b(x) = G (f(x) - A x)``)."""
    q = np.asarray(q, float)
    w = np.asarray(w, float)
    d = displacement_screw(robot, q, np.asarray(k_true, float), w)
    return SimulatedCampaigns(q=q[None], w=w[None], d=d[None], J=jacobian(robot, q)[None],
                              q_true=q, w_true=w)


def identify_campaigns(
    robot: RobotModel,
    sim: SimulatedCampaigns,
    noise: NoiseModel,
    x_weights: np.ndarray,
    method: str = "wls",
) -> np.ndarray:
    """Compliances (T, n) (rad/(N m)) of the simulated campaigns.

    ``wls`` whitens each row by its residual covariance at compliances
    ``x_weights`` (n,); ``ols`` leaves the rows unweighted; ``exact`` runs the
    batched Gauss-Newton fit from the WLS estimate.
    """
    T, m, n = sim.q.shape
    A = design_block(sim.J, sim.w)  # (T, m, 6, n)
    d = sim.d
    if method in ("wls", "exact"):
        J0 = jacobian(robot, sim.q_true)
        C = np.einsum("mij,j,mkj->mik", J0, x_weights, J0)
        Linv = np.linalg.inv(np.linalg.cholesky(residual_covariance(noise, C, sim.w_true)))
        A = np.einsum("mij,tmjp->tmip", Linv, A)
        d = np.einsum("mij,tmj->tmi", Linv, d)
    elif method != "ols":
        raise ValueError(f"unknown method {method!r}")
    x, _, _ = mgs_lstsq(np.ascontiguousarray(A.reshape(T, 6 * m, n).transpose(2, 1, 0)),
                        np.ascontiguousarray(d.reshape(T, 6 * m).T), with_rinv=False)
    x = x.T
    if method != "exact":
        return x
    gn = gauss_newton(robot, sim.q, sim.w, sim.d, np.ones(sim.d.shape, bool), tuple(range(n)),
                      noise, x)
    return gn.x
