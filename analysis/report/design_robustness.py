"""Robustness curve of the campaign's own design (cf. the paper's Fig. 7).

The paper draws poses at random in the good zones; here the question is
"how much would the spread shrink with more tests like these?". A trial of
``n`` tests repeats each of the campaign's ``m`` distinct tests (pose +
wrench) ``n // m`` times and adds ``n % m`` of them chosen at random (for
``n < m``: ``n`` distinct tests at random), so at ``n`` equal to the
campaign's size the trial is the campaign's own design. Each trial simulates
the exact displacement (nonlinear equilibrium) at the reference stiffness,
adds the noise model's normal noise to the displacement, wrench and joint
angles, and identifies with the paper's linear model (eqs. 16-18), weighted
by each test's measurement covariance (displacement noise plus the wrench
noise through the compliance; :func:`analysis.identification.studies.robustness.identify_batch`).
The Jacobian is evaluated at the noisy joint angles, as a real
identification would.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.noise import NoiseModel
from analysis.identification.studies.robustness import identify_batch
from analysis.kinetostatics.equilibrium import EquilibriumError, displacement_screw
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

DEFAULT_TESTS = (3, 4, 5, 6, 8, 10, 15, 20)
#: a number of tests leaves the design not identifiable when more than this fraction of
#: the trials give no positive finite k, or the spread (IQR / 1.349) exceeds the value
UNIDENTIFIABLE_FAILED = 0.10
UNIDENTIFIABLE_SPREAD = 1.0
#: IQR of a normal distribution in standard deviations: IQR / 1.349 estimates the std
IQR_PER_SIGMA = 1.349


Q_TOL = 1e-3  # rad: joint angles closer than this are one pose
W_TOL = 50.0  # N, N m: measured wrenches closer than this are one load case


def design_tests(q: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distinct (pose, load) pairs of a campaign: q (m, 6) rad, w (m, 6) N, N m.

    Measured angles and wrenches of repeats differ by noise, so pairs are
    grouped on a grid of :data:`Q_TOL` and :data:`W_TOL`; the first of each
    group is kept, in the campaign's order.
    """
    key = np.hstack([np.round(q / Q_TOL), np.round(w / W_TOL)])
    _, idx = np.unique(key, axis=0, return_index=True)
    idx = np.sort(idx)
    return q[idx], w[idx]


def draw_tests(m: int, n: int, trials: int, rng: np.random.Generator) -> np.ndarray:
    """Indices (trials, n) into m design tests: each ``n // m`` times, plus ``n % m`` distinct."""
    base = np.tile(np.arange(m), n // m)
    extra = np.argsort(rng.random((trials, m)), axis=1)[:, : n % m]
    return np.hstack([np.broadcast_to(base, (trials, base.size)), extra])


def design_robustness(
    robot: RobotModel,
    q: np.ndarray,
    w: np.ndarray,
    k_ref: np.ndarray,
    noise: NoiseModel,
    joints: Sequence[int],
    tests: Sequence[int] = DEFAULT_TESTS,
    trials: int = 300,
    seed: int = 0,
) -> pd.DataFrame:
    """Spread of the identified k against the number of tests drawn from the design.

    Parameters
    ----------
    q, w : (m, 6) design poses (rad) and wrenches (N, N m).
    k_ref : (6,) reference joint stiffness (N m/rad), e.g. the identified values.
    noise : measurement noise model (SI sigmas).
    joints : 0-based joints identified (the others rigid).

    Returns
    -------
    One row per (n_tests, joint): ``n_tests``, ``joint`` (1-based), ``relative_std``
    (std of k / k_ref), ``relative_bias`` (median k / k_ref - 1), ``relative_q25``,
    ``relative_q75`` (quartiles of k / k_ref - 1), ``relative_iqr`` (their difference),
    ``robust_sigma`` (relative_iqr / 1.349: the std of a normal spread, robust to the
    few wild draws of an ill-conditioned design), ``trials_used`` and ``identifiable``
    (False when more than :data:`UNIDENTIFIABLE_FAILED` of the trials fail or
    robust_sigma exceeds :data:`UNIDENTIFIABLE_SPREAD`).
    """
    if trials < 10:
        raise InputError("need at least 10 trials", where="--trials")
    q, w = design_tests(np.asarray(q, float), np.asarray(w, float))
    k_ref = np.asarray(k_ref, dtype=float)
    try:
        d_true = displacement_screw(robot, q, k_ref, w)
    except EquilibriumError as err:
        raise InputError(f"robustness study: {err}", where="--wrench") from err
    rng = np.random.default_rng(seed)
    cols = list(joints)
    rows = []
    for n in tests:
        idx = draw_tests(len(q), n, trials, rng)
        dq = rng.normal(size=(trials, n, 6)) * noise.joint_sigma
        J = jacobian(robot, q[idx] + dq)
        wn = w[idx] + rng.normal(size=(trials, n, 6)) * noise.wrench_sigma
        d = d_true[idx] + rng.normal(size=(trials, n, 6)) * noise.displacement_sigma
        # (T, n, r, j) -> the (j, r, n, T) layout of the batched identification
        x, _ = identify_batch(np.transpose(J, (3, 2, 1, 0)), np.transpose(wn, (2, 1, 0)),
                              np.transpose(d, (2, 1, 0)), noise, method="wls", joints=cols,
                              with_se=False)
        x = x.T
        ok = np.all(np.isfinite(x), axis=1) & np.all(x > 0, axis=1)
        for c, j in enumerate(cols):
            kk = 1.0 / x[ok, c]
            q25, q75 = (np.percentile(kk, [25, 75]) / k_ref[j] - 1 if ok.sum() > 3
                        else (np.nan, np.nan))
            spread = (q75 - q25) / IQR_PER_SIGMA
            rows.append({
                "n_tests": int(n), "joint": j + 1,
                "relative_std": float(np.std(kk, ddof=1) / k_ref[j]) if ok.sum() > 1 else np.nan,
                "relative_bias": float(np.median(kk) / k_ref[j] - 1) if ok.any() else np.nan,
                "trials_used": int(ok.sum()),
                "relative_q25": float(q25), "relative_q75": float(q75),
                "relative_iqr": float(q75 - q25), "robust_sigma": float(spread),
                "identifiable": bool(ok.sum() >= (1 - UNIDENTIFIABLE_FAILED) * trials
                                     and np.isfinite(spread)
                                     and spread <= UNIDENTIFIABLE_SPREAD),
            })
    return pd.DataFrame(rows)
