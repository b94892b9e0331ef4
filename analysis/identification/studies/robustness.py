"""Robustness of the identification to measurement noise (the paper's section 5, Fig. 7).

Monte-Carlo: each trial identifies the joint stiffness from ``n`` tests at
poses drawn from the good zones, with normal noise on the measured
displacement (translation and rotation), the measured wrench and the
measured joint angles, and the spread of the identified k is reported
against ``n``.

How a trial is simulated
------------------------
* A pool of ``pool_size`` poses is drawn once: zone chosen uniformly among
  the robot's zones (uniform in each zone's ranges, other joints uniform
  within their limits), or the whole joint range for robots without zones;
  poses with 1/kappa_F(J_N) below ``min_inverse_condition`` are redrawn
  (this also keeps the random wrist away from its singularity).
* The true displacement of every pool pose under the true wrench comes from
  the nonlinear equilibrium (:func:`analysis.kinetostatics.equilibrium.displacement_screw`),
  not from the linear model being fitted.
* A trial picks ``n`` pool poses at random (with replacement) and adds
  noise: d + N(0, sigma_d), w + N(0, sigma_w), q + N(0, sigma_q). The
  measured Jacobian J(q + dq_noise) is evaluated to first order from the
  pool's dJ/dq (error O(sigma_q^2), below 1e-10 relative).
* Identification is batched over trials (:mod:`analysis.identification.linalg.batch_lsq`, batch
  on the last axis): per-test whitening by Cholesky factors and QR by
  modified Gram-Schmidt, ``ols`` (the paper's estimator, without the
  linearisation-bias correction of ``campaign analyze``: the study as the paper
  made it) or ``wls``; or ``exact`` (default, as in ``campaign analyze``): batched
  Gauss-Newton on the equilibrium (:mod:`analysis.identification.estimators.gauss_newton`) from
  the OLS start, about 100 times slower,
  which removes the linearisation bias the linear fits show at large loads.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from analysis.choices import LINEARISED_METHODS, METHODS
from analysis.errors import InputError
from analysis.identification.estimators.gauss_newton import gauss_newton
from analysis.identification.linalg.batch_lsq import CHUNK, cholesky, forward_substitute, mgs_lstsq
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.dexterity import (
    characteristic_length,
    inverse_condition,
    normalized_jacobian,
)
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

#: The paper's eq. 22 wrench [fx fy fz (N); mx my mz (N m)].
W_EFF = np.array([0.0, 2200.0, 2200.0, 200.0, 200.0, 0.0])
MIN_INVERSE_CONDITION = 0.2
SE_TRIALS = 2000  # trials on which the predicted standard errors are computed
TRIAL_CHUNK_TESTS = 40_000  # trials x tests per chunk (memory: ~10 kB per test)
EXACT_CHUNK_TESTS = 5_000  # the exact fit is ~100 x slower: smaller chunks, finer progress


@dataclass(frozen=True)
class PosePool:
    """Poses with their Jacobians and exact displacements (SI), stored pose-first.

    q (P, 6) rad; Jp (P, 6, 6) Jacobian by column: Jp[i, j, r] = J_i[r, j];
    dJp (P, 6, 6, 6) with dJp[i, k] = dJp[i]/dq_k; d (6, P) displacement [m; rad]
    under ``w`` (6,) (N, N m) for joint stiffness ``k`` (6,) (N m/rad).

    Pose-first, drawing tests copies each pose's 36 (216) contiguous numbers; the
    batch-last views :attr:`Jc` and :attr:`dJc` are what the kernels read.
    """

    q: np.ndarray
    Jp: np.ndarray
    dJp: np.ndarray
    d: np.ndarray
    w: np.ndarray
    k: np.ndarray

    @property
    def Jc(self) -> np.ndarray:
        """(6, 6, P) view, batch last: Jc[j, r] = J[r, j]."""
        return np.moveaxis(self.Jp, 0, -1)

    @property
    def dJc(self) -> np.ndarray:
        """(6, 6, 6, P) view, batch last: dJc[k] = dJc/dq_k."""
        return np.moveaxis(self.dJp, 0, -1)


def sample_poses(
    robot: RobotModel,
    count: int,
    rng: np.random.Generator,
    min_inverse_condition: float = MIN_INVERSE_CONDITION,
    length: float | None = None,
    max_rounds: int = 200,
) -> np.ndarray:
    """``count`` poses (rad) in the robot's zones (or joint range) with 1/kappa_F >= threshold."""
    if length is None:
        length = robot.characteristic_length or characteristic_length(robot, starts=3)[0]
    out: list[np.ndarray] = []
    have = 0
    for _ in range(max_rounds):
        batch = max(64, 2 * (count - have))
        q = rng.uniform(robot.lower, robot.upper, (batch, robot.n))
        if robot.zones:
            z = rng.integers(0, len(robot.zones), batch)
            for i, zone in enumerate(robot.zones):
                sel = z == i
                for j, (lo, hi) in zone.ranges.items():
                    lo, hi = max(lo, robot.lower[j]), min(hi, robot.upper[j])
                    q[sel, j] = rng.uniform(lo, hi, int(sel.sum()))
        ic = inverse_condition(normalized_jacobian(jacobian(robot, q), length))
        good = q[ic >= min_inverse_condition]
        out.append(good)
        have += len(good)
        if have >= count:
            return np.concatenate(out)[:count]
    raise InputError(
        f"fewer than {count} poses with 1/kappa_F >= {min_inverse_condition:g} found in "
        f"{max_rounds} rounds of sampling; lower the threshold", where="--min-dexterity",
    )


def jacobian_derivative(robot: RobotModel, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """dJ/dq (..., 6, n, n) by central differences (last axis: joint differentiated)."""
    n = q.shape[-1]
    cols = [(jacobian(robot, q + h * e) - jacobian(robot, q - h * e)) / (2 * h)
            for e in np.eye(n)]
    return np.stack(cols, axis=-1)


def build_pool(
    robot: RobotModel,
    k: np.ndarray,
    w: np.ndarray,
    size: int,
    rng: np.random.Generator,
    min_inverse_condition: float = MIN_INVERSE_CONDITION,
) -> PosePool:
    """Draw ``size`` poses and simulate their exact displacement under ``w``."""
    q = sample_poses(robot, size, rng, min_inverse_condition)
    w = np.asarray(w, dtype=float)
    d = displacement_screw(robot, q, k, np.broadcast_to(w, (size, 6)))
    J = jacobian(robot, q)  # (P, r, j)
    dJ = jacobian_derivative(robot, q)  # (P, r, j, k)
    return PosePool(
        q=q,
        Jp=np.ascontiguousarray(np.transpose(J, (0, 2, 1))),
        dJp=np.ascontiguousarray(np.transpose(dJ, (0, 3, 2, 1))),
        d=np.ascontiguousarray(d.T),
        w=w,
        k=np.asarray(k, float),
    )


def _test_covariance(Jc, x_full, noise: NoiseModel) -> np.ndarray:
    """Per-test residual covariance (6, 6, n, T) for compliances x_full (6, T).

    diag(sigma_d^2) + C diag(sigma_w^2) C^T with C = J diag(x) J^T, by
    symmetric pairs of two-operand contractions (faster than one einsum).
    """
    Jx = Jc * x_full[:, None, None, :]
    shape = Jc.shape[1:2] * 2 + Jc.shape[2:]
    C = np.empty(shape)
    cov = np.empty(shape)
    for a in range(6):
        for b in range(a, 6):
            C[a, b] = np.einsum("jnt,jnt->nt", Jx[:, a], Jc[:, b])
            C[b, a] = C[a, b]
    Cw = C * (noise.wrench_sigma**2)[None, :, None, None]
    for a in range(6):
        for b in range(a, 6):
            cov[a, b] = np.einsum("jnt,jnt->nt", Cw[a], C[b])
            cov[b, a] = cov[a, b]
    cov[np.arange(6), np.arange(6)] += (noise.displacement_sigma**2)[:, None, None]
    return cov


def identify_batch(
    Jc: np.ndarray,
    w: np.ndarray,
    d: np.ndarray,
    noise: NoiseModel,
    method: str = "wls",
    joints: Sequence[int] = tuple(range(6)),
    with_se: bool = True,
    reweight: int = 1,
) -> tuple[np.ndarray, np.ndarray | None]:
    """Identify joint compliances for many trials at once (linear model, eqs. 16-18).

    Parameters
    ----------
    Jc : (6, 6, n, T) measured Jacobians by column (Jc[j, r] = J[r, j]) for n
        tests of T trials; w : (6, n, T) measured wrenches (N, N m);
    d : (6, n, T) measured displacements (m, rad); method : "ols" or "wls".
    reweight : WLS passes, each re-evaluating the wrench-noise term of the
        weights at the previous estimate (the first from OLS).

    No wrench errors-in-variables correction
    (:mod:`analysis.identification.corrections.wrench_eiv`, which
    ``identify`` applies): at the 5-50 tests of a planned campaign it moves x by a few
    hundredths of a standard error, below what these Monte-Carlo figures resolve.

    Returns
    -------
    x : (p, T) compliances (rad/(N m)); se : (p, T) standard errors predicted
        by the noise model (WLS: (A^T Sigma^-1 A)^-1; OLS: the sandwich
        A^+ Sigma A^+T), or None when ``with_se`` is False.
    """
    if method not in LINEARISED_METHODS:
        raise InputError(f"identify_batch supports ols and wls, not {method!r} (the exact "
                         "fit is identify_exact_batch)", where="--method")
    cols = list(joints)
    T = w.shape[-1]
    x = np.empty((len(cols), T))
    se = np.empty((len(cols), T)) if with_se else None
    # blocks of trials small enough to stay in cache: every step below is a
    # vectorised operation over the trials of one block
    for s in range(0, T, CHUNK):
        sl = slice(s, min(T, s + CHUNK))
        xs, ses = _identify_block(Jc[..., sl], w[..., sl], d[..., sl], noise, method, cols,
                                  with_se, reweight)
        x[:, sl] = xs
        if with_se:
            se[:, sl] = ses
    return x, se


def _identify_block(Jc, w, d, noise, method, cols, with_se, reweight):
    p, (_, n, T) = len(cols), w.shape
    Jp = Jc[cols]
    tau = np.einsum("jrnt,rnt->jnt", Jp, w)
    A = Jp * tau[:, None]  # (p, r, n, T)
    x, Rinv, scale = mgs_lstsq(A.reshape(p, 6 * n, T), d.reshape(6 * n, T),
                               with_rinv=with_se and method == "ols", chunk=T)
    if method == "ols":
        if not with_se:
            return x, None
        cov_unit = np.einsum("ijt,kjt->ikt", Rinv, Rinv) / (scale[:, None] * scale[None])
        G = np.einsum("pqt,qrnt->prnt", cov_unit, A, optimize=True)
        cov_x = np.einsum("pant,abnt,qbnt->pqt", G, _test_covariance(Jc, _full(x, cols), noise),
                          G, optimize=True)
        return x, np.sqrt(np.einsum("ppt->pt", cov_x))
    A_rows = np.moveaxis(A, 1, 0)  # (r, p, n, T)
    for _ in range(reweight):
        L = cholesky(_test_covariance(Jc, _full(x, cols), noise))
        Aw = np.moveaxis(forward_substitute(L, A_rows), 0, 1).reshape(p, 6 * n, T)
        dw = forward_substitute(L, d).reshape(6 * n, T)
        x, Rinv, scale = mgs_lstsq(Aw, dw, with_rinv=with_se, chunk=T)
    if not with_se:
        return x, None
    var = np.einsum("ijt,ijt->it", Rinv, Rinv) / scale**2
    return x, np.sqrt(var)


def _full(x: np.ndarray, cols: list[int]) -> np.ndarray:
    out = np.zeros((6, x.shape[-1]))
    out[cols] = x
    return out


@dataclass(frozen=True)
class Draw:
    """Noisy campaigns drawn from a pool (batch last): idx (n, T) pool indices;
    dq (6, n, T) joint-angle noise (rad); w (6, n, T) measured wrench (N, N m);
    d (6, n, T) measured displacement (m, rad)."""

    idx: np.ndarray
    dq: np.ndarray
    w: np.ndarray
    d: np.ndarray


def draw_campaigns(
    pool: PosePool, n_tests: int, trials: int, noise: NoiseModel, rng: np.random.Generator
) -> Draw:
    """Pick ``n_tests`` pool poses per trial (with replacement) and draw the noise."""
    idx = rng.integers(0, pool.q.shape[0], (n_tests, trials))
    dq = rng.normal(size=(6, n_tests, trials)) * noise.joint_sigma
    w = pool.w[:, None, None] + rng.normal(size=(6, n_tests, trials)) \
        * noise.wrench_sigma[:, None, None]
    d = pool.d[:, idx] + rng.normal(size=(6, n_tests, trials)) \
        * noise.displacement_sigma[:, None, None]
    return Draw(idx, dq, w, d)


def measured_jacobians(pool: PosePool, draw: Draw) -> np.ndarray:
    """Jc (6, 6, n, T) at the measured (noisy) joint angles, first order in the noise.

    Gathered pose-first (each test copies its pose's contiguous 36 + 216 numbers),
    the first-order term J += sum_k dJ/dq_k dq_k as one contraction per test, then
    laid out batch last for the kernels (2.2x the batch-last gather, measured).
    """
    idx = draw.idx.T.reshape(-1)  # trial-major, so the result transposes to (.., n, T)
    T, n = draw.idx.shape[1], draw.idx.shape[0]
    dq = np.transpose(draw.dq, (2, 1, 0)).reshape(-1, 6)
    J = pool.Jp.reshape(-1, 36)[idx] + np.einsum(
        "bk,bkx->bx", dq, pool.dJp.reshape(-1, 6, 36)[idx])
    return np.ascontiguousarray(J.reshape(T, n, 6, 6).transpose(2, 3, 1, 0))


def simulate_measurements(
    pool: PosePool, n_tests: int, trials: int, noise: NoiseModel, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Noisy (Jc (6, 6, n, T), w (6, n, T), d (6, n, T)) for tests drawn from the pool."""
    draw = draw_campaigns(pool, n_tests, trials, noise, rng)
    return measured_jacobians(pool, draw), draw.w, draw.d


def identify_exact_batch(
    robot: RobotModel, pool: PosePool, draw: Draw, noise: NoiseModel,
    joints: Sequence[int] = tuple(range(6)),
) -> tuple[np.ndarray, np.ndarray]:
    """Exact (Gauss-Newton) fits of drawn campaigns, started from batched OLS.

    Returns x (p, T) and se (p, T), NaN for campaigns whose equilibrium could
    not be solved at the estimate (absurd OLS starts with one or two tests).
    """
    cols = tuple(joints)
    x0, _ = identify_batch(measured_jacobians(pool, draw), draw.w, draw.d, noise, "ols", cols,
                           with_se=False)
    q = pool.q[draw.idx.T] + np.transpose(draw.dq, (2, 1, 0))  # (T, n, 6)
    w = np.transpose(draw.w, (2, 1, 0))
    d = np.transpose(draw.d, (2, 1, 0))
    gn = gauss_newton(robot, q, w, d, np.ones(d.shape, bool), cols, noise, x0.T)
    se = np.sqrt(np.diagonal(gn.cov_x, axis1=-2, axis2=-1))
    return gn.x.T, se.T


def noise_free_bias(pool: PosePool, draw: Draw, noise: NoiseModel, method: str,
                    joints: Sequence[int], k_true: np.ndarray) -> np.ndarray:
    """(p,) mean over the drawn campaigns of k / k_true - 1 of the linear ``method``
    fitted to their noise-free data (the pool's exact displacements, exact wrench and
    joint angles): the linearisation bias of the linear model at this wrench, alone.
    The mean, as the Monte-Carlo mean it is compared with (the designs' biases are
    skewed: their median was up to 0.3 % of k off that mean for wls, k5 at w_eff).
    ``noise`` only weights WLS. NaN for a joint no campaign identifies."""
    n, T = draw.idx.shape
    clean = Draw(draw.idx, np.zeros_like(draw.dq),
                 np.broadcast_to(pool.w[:, None, None], (6, n, T)).copy(),
                 pool.d[:, draw.idx])
    x, _ = identify_batch(measured_jacobians(pool, clean), clean.w, clean.d, noise, method,
                          tuple(joints), with_se=False)
    with np.errstate(invalid="ignore", divide="ignore"):
        rel = np.where(x > 0, 1.0 / x, np.nan) / k_true[list(joints), None] - 1.0
    out = np.full(len(joints), np.nan)
    for c in range(len(joints)):
        good = rel[c][np.isfinite(rel[c])]
        if good.size:
            out[c] = float(np.mean(good))
    return out


def _summary_rows(n: int, x: np.ndarray, se: np.ndarray, k_true, joints,
                  bias: np.ndarray | None = None) -> list[dict]:
    x, se = x.T, se.T  # (T, p)
    rows = []
    with np.errstate(invalid="ignore"):
        ok = np.all(np.isfinite(x), axis=1) & np.all(x > 0, axis=1)
    for c, j in enumerate(joints):
        kk = 1.0 / x[ok, c]
        xs, ok_s = x[: se.shape[0], c], ok[: se.shape[0]]
        pred = np.median(se[ok_s, c] / xs[ok_s] ** 2) if ok_s.any() else np.nan
        q25, q50, q75 = np.percentile(kk, [25, 50, 75]) if ok.any() else (np.nan,) * 3
        rows.append({
            "n_tests": n, "joint": j + 1, "k_true_Nm_per_rad": float(k_true[j]),
            "mean_Nm_per_rad": float(np.mean(kk)) if ok.any() else np.nan,
            "std_Nm_per_rad": float(np.std(kk, ddof=1)) if ok.sum() > 1 else np.nan,
            "relative_std": float(np.std(kk, ddof=1) / k_true[j]) if ok.sum() > 1 else np.nan,
            "median_Nm_per_rad": float(q50),
            "iqr_Nm_per_rad": float(q75 - q25),
            "q25_Nm_per_rad": float(q25), "q75_Nm_per_rad": float(q75),
            "predicted_std_Nm_per_rad": float(pred),
            "std_compliance_rad_per_Nm": float(np.nanstd(x[:, c], ddof=1)),
            "trials": int(x.shape[0]),
            "trials_rejected": int((~ok).sum()),
            "trials_failed": int((~np.all(np.isfinite(x), axis=1)).sum()),
            "linearisation_bias_relative": np.nan if bias is None else float(bias[c]),
        })
    return rows


def robustness_study(
    robot: RobotModel,
    k_true: np.ndarray,
    wrench: np.ndarray = W_EFF,
    tests: Sequence[int] = range(1, 21),
    trials: int = 1000,
    noise: NoiseModel | None = None,
    method: str = "exact",
    seed: int = 0,
    pool_size: int = 2000,
    min_inverse_condition: float = MIN_INVERSE_CONDITION,
    progress: Callable[[int], None] | None = None,
) -> pd.DataFrame:
    """Mean and spread of the identified k against the number of tests.

    Returns one row per (n_tests, joint): k_true, mean, std (ddof 1), relative
    std (std / k_true), median, IQR, the median noise-model prediction of the
    std (delta method), the std of the compliance, trials, trials rejected
    (some x <= 0 or not finite: excluded from the statistics of k), and for ols/wls
    the linearisation bias (:func:`noise_free_bias`, NaN for exact).
    ``progress(trials_done)`` is called after each chunk.
    """
    noise = noise or NoiseModel()
    k_true = np.asarray(k_true, dtype=float)
    if k_true.shape != (robot.n,) or np.any(~np.isfinite(k_true)) or np.any(k_true <= 0):
        raise InputError(f"expected {robot.n} positive joint stiffness values (N m/rad)",
                         where="--joint-stiffness")
    wrench = np.asarray(wrench, dtype=float)
    if wrench.shape != (6,) or not np.all(np.isfinite(wrench)) or not np.any(wrench):
        raise InputError("expected 6 finite numbers, not all zero (N, N m)", where="--wrench")
    if trials < 2:
        raise InputError("need at least 2 trials", where="--trials")
    if method not in METHODS:
        raise InputError(f"expected {', '.join(METHODS[:-1])} or {METHODS[-1]}, got {method!r}",
                         where="--method")
    tests = list(tests)
    if not tests or min(tests) < 1:
        raise InputError("numbers of tests must be >= 1", where="--tests")
    rng = np.random.default_rng(seed)
    pool = build_pool(robot, k_true, wrench, pool_size, rng, min_inverse_condition)
    joints = tuple(range(robot.n))
    rows = []
    for n in tests:
        chunk = max(1, (EXACT_CHUNK_TESTS if method == "exact" else TRIAL_CHUNK_TESTS) // n)
        xs, ses = [], []
        bias = None
        done = 0
        while done < trials:
            t = min(chunk, trials - done)
            draw = draw_campaigns(pool, n, t, noise, rng)
            if method == "exact":
                x, se = identify_exact_batch(robot, pool, draw, noise, joints)
                ses.append(se)
            else:
                J = measured_jacobians(pool, draw)
                x, _ = identify_batch(J, draw.w, draw.d, noise, method, joints, with_se=False)
                if not ses:  # the noise-model prediction of the spread, from a subset
                    sub = slice(0, min(t, SE_TRIALS))
                    ses.append(identify_batch(J[..., sub], draw.w[..., sub], draw.d[..., sub],
                                              noise, method, joints)[1])
                    # and the linear model's own bias, on the same campaigns without noise
                    bias = noise_free_bias(pool, Draw(draw.idx[:, sub], draw.dq[..., sub],
                                                      draw.w[..., sub], draw.d[..., sub]),
                                           noise, method, joints, k_true)
            xs.append(x)
            done += t
            if progress is not None:
                progress(t)
        rows += _summary_rows(n, np.concatenate(xs, axis=1), np.concatenate(ses, axis=1), k_true,
                              joints, bias)
    return pd.DataFrame(rows)
