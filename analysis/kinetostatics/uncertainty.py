"""Uncertainty of predictions made from an identified joint stiffness.

The identification gives the joint compliances x = 1/k (rad/(N m)) with their
covariance ``cov_x`` (n, n). Every prediction here is propagated from it:

* the deflection of P under a wrench, from the nonlinear equilibrium
  ``K_theta dq = J(q + dq)^T w`` (:mod:`analysis.kinetostatics.equilibrium`):
  implicit differentiation gives ``d(dq)/dx_j = M^-1 e_j k_j^2 dq_j`` with
  ``M = K_theta - K_C(q + dq)``, and ``d(dX)/dx = J(q + dq) d(dq)/dx``. For the
  linear model without K_C this is the design matrix A of eqs. 16-18, so the
  deflection is linear in x and the propagated covariance ``S cov_x S^T`` is
  exact; with K_C and the finite displacement it is the delta method (first
  order; the neglected terms are of the relative size of K_C and of the
  deflection angle, below 2 % of the interval half-width for industrial arms);
* K_X, which is linear in k (eq. 6 with K_C held at the wrench): its standard
  errors are exact given the covariance of k, itself from cov_x by the delta
  method (``dk_j/dx_j = -k_j^2``).

Intervals are normal: ``value +- z sd`` with ``z = 1.96`` for 95 %.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.kinetostatics.equilibrium import solve_deflection
from analysis.kinetostatics.stiffness import complementary_stiffness_from_state
from analysis.model.kinematics import chain_state, jacobian_from_state, pose_difference
from analysis.model.robot_model import RobotModel

#: two-sided 95 % normal quantile
Z95 = 1.959963984540054


def stiffness_covariance(k: np.ndarray, cov_x: np.ndarray) -> np.ndarray:
    """Covariance of k (n, n) ((N m/rad)^2) from that of x = 1/k (delta method)."""
    d = np.asarray(k, dtype=float) ** 2
    return np.asarray(cov_x, dtype=float) * d[:, None] * d[None, :]


@dataclass(frozen=True)
class DeflectionPrediction:
    """Predicted deflection of P and its covariance, batched over poses (SI).

    dq (..., n) joint deflection (rad); screw (..., 6) finite displacement of P
    ``[dp (m); rotation vector (rad)]``, base frame; sensitivity (..., 6, n)
    d screw / d x (m or rad per rad/(N m)); cov (..., 6, 6) covariance of the screw.
    """

    dq: np.ndarray
    screw: np.ndarray
    sensitivity: np.ndarray
    cov: np.ndarray

    @property
    def sd(self) -> np.ndarray:
        """Standard deviation (..., 6) of each component (m, rad)."""
        return np.sqrt(np.maximum(np.diagonal(self.cov, axis1=-2, axis2=-1), 0.0))

    def bounds(self, z: float = Z95) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (..., 6) of the ``+- z sd`` interval of each component."""
        return self.screw - z * self.sd, self.screw + z * self.sd

    def norm_upper(self, part: slice = slice(0, 3), z: float = Z95) -> np.ndarray:
        """Upper bound (...,) of |screw[part]| (delta method along its direction)."""
        return norm_upper_bound(self.screw[..., part], self.cov[..., part, part], z)


def norm_upper_bound(v: np.ndarray, cov: np.ndarray, z: float = Z95) -> np.ndarray:
    """|v| + z sd(|v|) (...,) with sd(|v|)^2 = u^T cov u, u = v/|v| (delta method).

    Where v = 0 the direction is undefined; the bound is then z sqrt(largest
    eigenvalue of cov), the worst direction.
    """
    norm = np.linalg.norm(v, axis=-1)
    safe = np.where(norm > 0, norm, 1.0)[..., None]
    u = v / safe
    var = np.einsum("...i,...ij,...j->...", u, cov, u)
    worst = np.linalg.eigvalsh(0.5 * (cov + np.swapaxes(cov, -1, -2)))[..., -1]
    var = np.where(norm > 0, var, worst)
    return norm + z * np.sqrt(np.maximum(var, 0.0))


def predict_deflection(
    robot: RobotModel,
    q: np.ndarray,
    k: np.ndarray,
    w: np.ndarray,
    cov_x: np.ndarray | None = None,
) -> DeflectionPrediction:
    """Deflection of P at q (..., n) (rad) under w (..., 6) (N, N m) with its covariance.

    k (n,) joint stiffness (N m/rad); cov_x (n, n) covariance of x = 1/k, None
    for a zero covariance (nominal model). A model file with link compliance adds the
    links' sum_l J_l C_l J_l^T w (:func:`~analysis.kinetostatics.link_compliance
    .link_screw`) and, with cov_x, the covariance of its identified entries (and their
    cross-covariance with x) when the file keeps it
    (:func:`~analysis.kinetostatics.link_compliance.link_covariance_terms`). A model file
    with the axis-2 compensator law has joint 2's stiffness at each pose's q2
    (:func:`~analysis.kinetostatics.compensator_law.pose_stiffness`; k is the file's);
    cov_x is then x2's at q2ref, moved to x2(q2)'s with the law's covariance when the file
    keeps it (:func:`~analysis.kinetostatics.compensator_law.pose_compliance_covariance`;
    else c1, c2 count as exact: dx2(q2)/dx2 = 1).
    """
    from analysis.kinetostatics.compensator_law import pose_compliance_covariance, pose_stiffness

    q = np.asarray(q, dtype=float)
    k = pose_stiffness(robot, q, np.asarray(k, dtype=float))  # k itself without the law
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    dq = solve_deflection(robot, q, k, w)
    loaded = chain_state(robot, q + dq)
    screw = pose_difference(chain_state(robot, q).tip, loaded.tip)
    from analysis.kinetostatics.link_compliance import link_screw

    screw = screw + link_screw(robot, q, w)  # a model file's link compliance (else 0)
    n = q.shape[-1]
    M = k[..., :, None] * np.eye(n) - complementary_stiffness_from_state(loaded, w)
    rhs = (k**2 * dq)[..., None, :] * np.eye(n)  # diag(k^2 dq), (..., n, n)
    S = jacobian_from_state(loaded) @ np.linalg.solve(M, rhs)
    if cov_x is None:
        cov = np.zeros((*q.shape[:-1], 6, 6))
    else:
        from analysis.kinetostatics.link_compliance import link_covariance_terms

        # + the link entries' covariance and their cross-covariance with x (model file's
        # [model_class.link_covariance]; zeros without)
        cov_q = pose_compliance_covariance(robot, q, np.asarray(cov_x, dtype=float))
        cov = (S @ cov_q @ np.swapaxes(S, -1, -2) + link_covariance_terms(robot, q, w, S))
    return DeflectionPrediction(dq, screw, S, cov)


def cartesian_stiffness_se(J: np.ndarray, cov_k: np.ndarray) -> np.ndarray:
    """Standard error (..., 6, 6) of every entry of K_X = J^-T (K_theta - K_C) J^-1.

    K_X is linear in k: dK_X/dk_j = outer(J^-1[j], J^-1[j]); K_C depends on the
    wrench only, so the same errors hold with and without it. Units: those of K_X.
    """
    Jinv = np.linalg.inv(J)
    G = Jinv[..., :, :, None] * Jinv[..., :, None, :]  # (..., j, a, b)
    var = np.einsum("...jab,jl,...lab->...ab", G, np.asarray(cov_k, dtype=float), G)
    return np.sqrt(np.maximum(var, 0.0))


def principal_stiffness(K_X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal translational (N/m) and rotational (N m/rad) stiffness of K_X (..., 6, 6).

    The stiffness P shows under a pure force (resp. a pure moment): the
    inverses of the eigenvalues of the translational (resp. rotational) block
    of the compliance K_X^-1 (symmetric part), largest first. Returns
    ((..., 3), (..., 3)).
    """
    C = np.linalg.inv(K_X)
    C = 0.5 * (C + np.swapaxes(C, -1, -2))
    out = []
    for part in (slice(0, 3), slice(3, 6)):
        ev = np.linalg.eigvalsh(C[..., part, part])  # ascending compliance
        out.append(1.0 / ev)  # descending stiffness
    return out[0], out[1]


def linear_deflection_upper_bound(
    robot: RobotModel, q: np.ndarray, k: np.ndarray, w: np.ndarray, cov_x: np.ndarray,
    z: float = Z95,
) -> np.ndarray:
    """Upper bound (...,) (m) of |dp| of the linear deflection with K_C (the maps' model).

    dX = J M^-1 J^T w with M = K_theta - K_C, so d(dX)/dx_j = J M^-1 e_j k_j^2 dq_j
    with dq = M^-1 J^T w: the same sensitivity as the equilibrium's, at the
    unloaded pose. Delta method along the direction of dp (:func:`norm_upper_bound`).
    A model file with link compliance adds the links' displacement and its entries'
    covariance (:mod:`analysis.kinetostatics.link_compliance`); one with the axis-2
    compensator law has k2(q2) at each pose (k the file's) and x2(q2)'s covariance
    (:func:`~analysis.kinetostatics.compensator_law.pose_compliance_covariance`).
    """
    from analysis.kinetostatics.compensator_law import pose_compliance_covariance, pose_stiffness

    q = np.asarray(q, dtype=float)
    k = pose_stiffness(robot, q, np.asarray(k, dtype=float))  # k itself without the law
    w = np.broadcast_to(np.asarray(w, dtype=float), (*q.shape[:-1], 6))
    n = q.shape[-1]
    state = chain_state(robot, q)
    J = jacobian_from_state(state)
    M = k[..., :, None] * np.eye(n) - complementary_stiffness_from_state(state, w)
    dq = np.linalg.solve(M, np.einsum("...ji,...j->...i", J, w)[..., None])[..., 0]
    S = J[..., :3, :] @ np.linalg.solve(M, (k**2 * dq)[..., None, :] * np.eye(n))
    from analysis.kinetostatics.link_compliance import link_covariance_terms, link_screw

    # a model file's link compliance: its displacement and its entries' covariance
    cov_q = pose_compliance_covariance(robot, q, np.asarray(cov_x, dtype=float))
    cov = (S @ cov_q @ np.swapaxes(S, -1, -2) + link_covariance_terms(robot, q, w, S))
    dp = np.einsum("...ij,...j->...i", J[..., :3, :], dq) + link_screw(robot, q, w)[..., :3]
    return norm_upper_bound(dp, cov, z)
