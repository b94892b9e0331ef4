"""Encoder noise in the joint angles that build the regressor: its bias, as a systematic term.

Every estimator evaluates J, and so A(q) = J diag(J^T w), at the *measured* joint
angles q_m = q + e, e ~ N(0, sigma_q^2 I) per joint. To second order in e,

    A(q_m) = A + sum_k A_k e_k + 1/2 sum_kl A_kl e_k e_l,   A_k = dA/dq_k,

and with the displacement measured at the true q (d = A x + noise, the nonlinear
term aside), the expectations of the normal equations of a weighted fit give the
bias of the compliances

    b_q = -N^-1 sigma_q^2 (S_q + 1/2 T_q) x,
    S_q = sum_tests sum_k A_k^T W A_k,   T_q = sum_tests sum_k A^T W A_kk,
    N = sum_tests A^T W A,

an attenuation like the wrench noise's (:mod:`analysis.identification.corrections.wrench_eiv`), of
relative order (sigma_q d ln J / dq)^2: ~1e-10 with the default 5 urad encoders.
It does not fall with the number of tests while the standard error does, so it is
added to every interval as a systematic term, ``x +- (c se + |b_q|)``
(:func:`encoder_bias`), and reported (results.json ``encoder_errors_in_variables``).
The remainder is of order sigma_q^4. N, S_q and T_q are summed over an evenly spaced
subset of at most :data:`MAX_TESTS` tests: b_q is a ratio of sums, the same on
average over any part of the campaign. The derivatives are central differences of
step :data:`STEP` (truncation ~STEP^2 ~1e-8 relative; rounding ~1e-16 / STEP^2 ~1e-8).
"""

from __future__ import annotations

import numpy as np

from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import whitening
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

#: tests on which the sums are taken (evenly spaced); ~0.05 s for 2000 tests
MAX_TESTS = 2000
#: finite-difference step of dA/dq and d2A/dq2 (rad)
STEP = 1e-4


def _subset(m: int) -> np.ndarray:
    if m <= MAX_TESTS:
        return np.arange(m)
    return np.unique(np.linspace(0, m - 1, MAX_TESTS).round().astype(np.int64))


def encoder_bias(robot: RobotModel, tests: TestArrays, joints: tuple[int, ...],
                 x: np.ndarray, noise: NoiseModel) -> np.ndarray:
    """b_q (p,) (rad/(N m)): the bias of the identified compliances ``x`` (p,) from the
    encoder noise in J (module docstring), weighted by the noise model at x."""
    cols = list(joints)
    sigma = float(noise.joint_sigma)
    p = len(cols)
    if sigma == 0.0 or tests.m == 0:
        return np.zeros(p)
    sub = tests.subset(_subset(tests.m))
    q, w, meas = sub.q, sub.w, sub.measured
    x_full = np.zeros(robot.n)
    x_full[cols] = x
    J0 = jacobian(robot, q)
    A0 = design_block(J0, w)[..., cols] * meas[..., None]
    C = (J0 * x_full[None, None, :]) @ np.swapaxes(J0, -1, -2)  # J diag(x) J^T
    L = whitening(residual_covariance(noise, C, w), meas)
    LA = L @ A0
    N = np.einsum("mri,mrj->ij", LA, LA)
    S, T = np.zeros((p, p)), np.zeros((p, p))
    for k in range(robot.n):
        dq = np.zeros(robot.n)
        dq[k] = STEP
        Ap = design_block(jacobian(robot, q + dq), w)[..., cols] * meas[..., None]
        Am = design_block(jacobian(robot, q - dq), w)[..., cols] * meas[..., None]
        LAk = L @ ((Ap - Am) / (2 * STEP))
        LAkk = L @ ((Ap - 2 * A0 + Am) / STEP ** 2)
        S += np.einsum("mri,mrj->ij", LAk, LAk)
        T += np.einsum("mri,mrj->ij", LA, LAkk)
    return -np.linalg.solve(N, sigma ** 2 * (S + 0.5 * T) @ x)


def summary(joints: tuple[int, ...], x: np.ndarray, bias: np.ndarray, se_x: np.ndarray,
            noise: NoiseModel, tests_used: int) -> dict:
    """results.json ``encoder_errors_in_variables``: the bias of each compliance (6
    entries, null for joints not identified), in standard errors and relative, and a
    note."""
    def per_joint(v):
        out = [None] * 6
        for j, val in zip(joints, v, strict=True):
            out[j] = float(val)
        return out

    in_se = np.abs(bias) / se_x
    worst = int(np.argmax(in_se))
    note = (f"encoder noise in J ({noise.joint_sigma * 1e6:.3g} urad per joint): bias of the "
            f"compliances up to {in_se[worst]:.2g} standard errors (joint "
            f"{joints[worst] + 1}, {abs(bias[worst] / x[worst]):.2g} relative), added to the "
            "intervals as a systematic term")
    return {
        "joint_sigma_urad": float(noise.joint_sigma * 1e6),
        "bias_of_compliance_rad_per_Nm": per_joint(bias),
        "bias_in_standard_errors": per_joint(in_se),
        "bias_relative": per_joint(np.abs(bias / x)),
        "tests_used": int(tests_used),
        "added_to_interval": True,
        "note": note,
    }
