"""Weighted Gauss-Newton fit of the exact equilibrium model, batched over campaigns.

Minimises sum_tests r^T Sigma^-1 r, r = d_measured - f(x), over the joint
compliances x, where f is the finite displacement of
:func:`analysis.identification.exact_fit.model_displacement`. The weights Sigma (per test,
:func:`analysis.identification.noise.residual_covariance`) are re-evaluated at the first
iterates. Each step solves the whitened linearised problem by QR; a step
that raises the cost is halved (per campaign) until it does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.identification import lsq
from analysis.identification.exact_fit import model_displacement_state
from analysis.identification.lsq import (
    qr_solve,
    stack_matrix,
    stack_vector,
    whitened_lstsq,
    whitening,
)
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel


@dataclass(frozen=True)
class GaussNewtonFit:
    """x (..., p) compliances (rad/(N m)); F (..., m, 6, p) model Jacobian at x;
    f (..., m, 6) model displacement (m, rad); cov (..., m, 6, 6) residual
    covariance per test; cov_x (..., p, p) covariance of x from the noise
    model, (F^T Sigma^-1 F)^-1; iterations; converged (...) bool; valid (...)
    bool: the model could be evaluated (x and cov_x are NaN where not); dq (..., m, 6)
    the joint deflections of the equilibrium at x (rad), Newton's warm start for
    later solves at nearby compliances; Linv (..., m, 6, 6) the whitening of cov
    (:func:`analysis.identification.lsq.whitening`)."""

    x: np.ndarray
    F: np.ndarray
    f: np.ndarray
    cov: np.ndarray
    cov_x: np.ndarray
    iterations: int
    converged: np.ndarray
    valid: np.ndarray
    dq: np.ndarray | None = None
    Linv: np.ndarray | None = None


#: tests per block when one campaign's model is evaluated: the equilibrium's working
#: arrays then stay in cache (measured 12.6 us/test in blocks of 4e3-1.6e4 tests, 41 us/test
#: as one block of 1e5)
EVAL_BLOCK = 8192


def _model_in_blocks(robot, q, x, w, with_jacobian, dq0=None, cols=None, measured=None,
                     out=None, tips=None):
    """:func:`model_displacement_state` for one campaign (q (m, 6)) in blocks of tests.

    ``dq0`` (..., m, 6): Newton's starting deflections (the previous iterate's), or None.
    Returns f, F (or None), ok, dq; F (..., m, 6, len(cols)) holds the columns ``cols``
    (default all) with zero rows where not ``measured`` (default all measured), made
    block by block.
    """
    # ``tips``: a dict kept by the caller across evaluations at the same q: the unloaded
    # tool poses (m, 4, 4), filled on first use (the unloaded chain does not depend on x)
    def select(F, sl=slice(None)):
        F = F if cols is None else F[..., cols]
        return F if measured is None else F * measured[sl][..., None]

    if q.ndim != 2 or q.shape[0] <= EVAL_BLOCK:
        f, F, ok, dq = model_displacement_state(robot, q, x, w, with_jacobian, dq0)
        return f, None if F is None else select(F), ok, dq
    m = q.shape[0]
    f, ok, dq = np.empty((m, 6)), np.empty(m, dtype=bool), np.empty(q.shape)
    if tips is not None and "tip" not in tips:
        tips["tip"] = np.empty((m, 4, 4))
        tips["filled"] = np.zeros(m, dtype=bool)
    shape = (m, 6, q.shape[-1] if cols is None else len(cols))
    # ``out``: a model Jacobian no longer needed, overwritten (its page faults are saved)
    F = (out if out is not None and out.shape == shape else np.empty(shape)) \
        if with_jacobian else None
    for s in range(0, m, EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        unloaded = None
        if tips is not None:  # the unloaded tool pose of each block, computed once
            unloaded = {"tip": tips["tip"][sl]} if tips["filled"][s] else {}
        fb, Fb, okb, dqb = model_displacement_state(robot, q[sl], x, w[sl], with_jacobian,
                                                    None if dq0 is None else dq0[sl],
                                                    unloaded=unloaded)
        if tips is not None and not tips["filled"][s]:
            tips["tip"][sl] = unloaded["tip"]
            tips["filled"][sl] = True
        f[sl], ok[sl], dq[sl] = fb, okb, dqb
        if with_jacobian:
            F[sl] = select(Fb, sl)
    return f, F, ok, dq


def _defined(Aw: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Aw with the systems of invalid campaigns replaced by I (keeps their QR defined)."""
    if np.all(valid):
        return Aw  # no copy (one campaign of 1e6 tests: 0.3 GB)
    return np.where(valid[..., None, None], Aw, np.eye(*Aw.shape[-2:]))


def covariances_per_test(noise, J, x_full, measured, w=None, weights=None,
                         out: np.ndarray | None = None) -> np.ndarray:
    """Residual covariance per test (..., m, 6, 6) at compliances x_full (..., 6).

    ``w`` (..., m, 6): the measured wrenches, for wrench noise proportional to the reading.
    ``weights`` (..., m, 6) > 0 where measured: robust weights
    (:mod:`analysis.identification.robust`); component i's variance is divided by
    weights_i and its correlations kept, Sigma_w = D^-1/2 Sigma D^-1/2 with D = diag(weights).
    One campaign (J (m, 6, 6)) is done in blocks of :data:`EVAL_BLOCK` tests
    (the (m, 6, 6) temporaries of 1e6 tests do not fit in cache).
    """
    if J.ndim == 3 and J.shape[0] > EVAL_BLOCK:
        # ``out``: an array to overwrite (one campaign), e.g. a covariance no longer needed
        out = np.empty(J.shape[:-1] + (6,)) if out is None else out
        for s in range(0, J.shape[0], EVAL_BLOCK):
            sl = slice(s, s + EVAL_BLOCK)
            out[sl] = covariances_per_test(noise, J[sl], x_full, measured[sl],
                                           None if w is None else w[sl],
                                           None if weights is None else weights[sl])
        return out
    C = (J * x_full[..., None, None, :]) @ np.swapaxes(J, -1, -2)  # J diag(x) J^T
    cov = residual_covariance(noise, C, w)
    if weights is not None:
        s = 1.0 / np.sqrt(np.where(measured, weights, 1.0))
        cov = cov * s[..., :, None] * s[..., None, :]
    return np.where(measured[..., :, None] & measured[..., None, :], cov, 0.0)


class PerTestCovariance:
    """The residual covariance of each test (m, 6, 6) of one large campaign, made when sliced.

    ``cov[s:e]`` is :func:`covariances_per_test` of those tests (the same numbers as a
    slice of the whole array); the (m, 6, 6) array (0.3 GB at 1e6 tests) is never held.
    The passes over it (:func:`analysis.identification.lsq.sandwich_and_residual_variance`,
    the chi-square's whitening, :func:`~analysis.identification.lsq.per_test_diagonal`)
    take it by blocks of consecutive tests. ``J`` (m, 6, 6) is the Jacobian at the tests'
    joint angles, ``x_full`` (6,) the compliances the covariances are evaluated at.
    """

    ndim = 3

    def __init__(self, noise, J, x_full, measured, w=None, weights=None) -> None:
        self.noise, self.J, self.measured, self.w, self.weights = noise, J, measured, w, weights
        self.x_full = np.array(x_full, dtype=float)
        self.shape = J.shape[:-1] + (6,)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, sl):
        if not isinstance(sl, slice):
            return np.asarray(self)[sl]

        def part(a):
            return None if a is None else a[sl]

        return covariances_per_test(self.noise, self.J[sl], self.x_full, self.measured[sl],
                                    part(self.w), part(self.weights))

    def __array__(self, dtype=None, copy=None):
        out = covariances_per_test(self.noise, self.J, self.x_full, self.measured, self.w,
                                   self.weights)
        return out if dtype is None else out.astype(dtype)


def per_test_covariance(noise, J, x_full, measured, w=None, weights=None):
    """:func:`covariances_per_test` as an array, or for one campaign of more than
    :data:`EVAL_BLOCK` tests a :class:`PerTestCovariance` (made block by block when used)."""
    if J.ndim == 3 and J.shape[0] > EVAL_BLOCK:
        return PerTestCovariance(noise, J, x_full, measured, w, weights)
    return covariances_per_test(noise, J, x_full, measured, w, weights)


def whitening_per_test(noise, J, x_full, measured, w=None, weights=None,
                       out: np.ndarray | None = None) -> np.ndarray:
    """:func:`whitening` of :func:`covariances_per_test`, block by block for one campaign.

    The same numbers as whitening the whole covariance array, without holding it
    (one campaign of 1e6 tests: 0.3 GB, and its page faults). ``out``: a whitening
    array no longer needed, overwritten.
    """
    if J.ndim != 3 or J.shape[0] <= EVAL_BLOCK:
        return whitening(covariances_per_test(noise, J, x_full, measured, w, weights),
                         measured)
    out = np.empty(J.shape[:-1] + (6,)) if out is None or out.shape != J.shape[:-1] + (6,) \
        else out
    for s in range(0, J.shape[0], EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        out[sl] = whitening(covariances_per_test(
            noise, J[sl], x_full, measured[sl], None if w is None else w[sl],
            None if weights is None else weights[sl]), measured[sl])
    return out


def gauss_newton(
    robot: RobotModel,
    q: np.ndarray,
    w: np.ndarray,
    d: np.ndarray,
    measured: np.ndarray,
    joints: tuple[int, ...],
    noise: NoiseModel,
    x0: np.ndarray,
    max_iter: int = 30,
    tol: float = 1e-9,
    reweight_iterations: int = 3,
    weights: np.ndarray | None = None,
    J: np.ndarray | None = None,
    Linv0: np.ndarray | None = None,
) -> GaussNewtonFit:
    """Fit compliances of ``joints`` (others rigid) to finite displacements.

    Parameters
    ----------
    q, w, d : (..., m, 6) joint angles (rad), wrenches (N, N m), displacements
        (m, rad; anything where not ``measured``); measured (..., m, 6) bool.
    x0 : (..., p) start (typically the OLS estimate).
    tol : stop when every step is below tol * max |x|. The model is solved
        to ~1e-15 rad, which makes the cost noisy at ~1e-10 relative: steps
        are accepted when the cost does not rise by more than 1e-8 relative.
    reweight_iterations : the weights follow x for this many iterations,
        then stay fixed so that the last iterations are plain Gauss-Newton.
    weights : (..., m, 6) robust weights > 0 where measured, or None (all 1); see
        :func:`covariances_per_test`. The returned ``cov`` and ``cov_x`` are the weighted ones.
    J : (..., m, 6, 6) the Jacobian at q, if the caller has it (computed otherwise).
    Linv0 : the whitening of the covariances at x0 (:func:`covariances_per_test` then
        :func:`analysis.identification.lsq.whitening`), if the caller has it: the first
        iteration's weights (it is overwritten by the later ones).
    """
    cols = list(joints)
    dz = np.where(measured, d, 0.0)
    J = jacobian(robot, q) if J is None else J
    batch = q.shape[:-2]

    def full(xp):
        out = np.zeros((*batch, 6))
        out[..., cols] = xp
        return out

    tips: dict = {}  # unloaded tool poses per test, shared by the evaluations

    def evaluate(xp, with_jacobian=True, dq0=None, out=None):
        # Newton warm-started at the deflections of the current iterate: the same
        # converged equilibrium (to its 1e-15 rad tolerance) in ~2 steps instead of ~4
        f, F, ok, dq = _model_in_blocks(robot, q, full(xp)[..., None, :], w, with_jacobian,
                                        dq0, cols, measured, out, tips)
        return f, F, np.all(ok, axis=-1), dq

    def whitened(Linv, f):
        return np.einsum("...ij,...j->...i", Linv, np.where(measured, dz - f, 0.0))

    def solve(Linv, F, f, r):
        """Gauss-Newton step and (F^T W F)^-1 of the whitened linearised system."""
        if F.ndim == 3 and F.shape[0] * 6 > lsq.TALL_ROWS and np.all(valid):
            # one large campaign: blockwise, without the stacked (6m, p) Linv F
            return whitened_lstsq(F, np.where(measured, dz - f, 0.0), Linv)
        if r is None:
            r = whitened(Linv, f)
        Aw = _defined(stack_matrix(Linv @ F), valid)
        step, cov_unit, _ = qr_solve(Aw, stack_vector(r), with_pinv=False)
        return step, cov_unit

    x = np.array(x0, dtype=float)
    valid = np.all(np.isfinite(x), axis=-1)
    x = np.where(valid[..., None], x, 0.0)
    f, F, ok, dq = evaluate(x)
    valid &= ok
    one_campaign = F.ndim == 3 and F.shape[0] > EVAL_BLOCK
    Linv = None
    converged = np.zeros(batch, dtype=bool)
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 (count kept after the loop)
        if iterations == 1 and Linv0 is not None and reweight_iterations >= 1:
            Linv = Linv0  # the caller's whitening at x0, the same array
        elif iterations <= reweight_iterations:
            # the previous iteration's whitening array is overwritten; the covariances
            # are made and whitened block by block (only the final ones are kept)
            Linv = whitening_per_test(noise, J, full(x), measured, w, weights, out=Linv)
        r = whitened(Linv, f)
        step, _ = solve(Linv, F, f, r)
        step = np.where(valid[..., None] & np.isfinite(step), step, 0.0)
        if iterations > 1:
            # a step below the tolerance is not taken: x is then within tol * max |x| of the
            # minimum, and its model, Jacobian and deflections are already evaluated (one
            # equilibrium solve saved, ~1/4 of the fit)
            small = np.max(np.abs(step), axis=-1) <= tol * np.max(np.abs(x), axis=-1)
            if np.all(small | ~valid):
                converged = small
                break
        # the next model Jacobian comes with the step's evaluation, into F's array
        F_buf = F if one_campaign else None
        del F
        cost0 = np.sum(r**2, axis=(-2, -1))
        t = np.ones(batch)
        accepted = np.zeros(batch, dtype=bool)
        # one campaign: the accepted trial's arrays are taken as they are (no (m, 6)
        # copies: ``ok`` is one bool), else merged campaign by campaign
        x_new, f_new, dq_new = (x, f, dq) if not batch else (x.copy(), f.copy(), dq.copy())
        F_full = None
        for halving in range(12):
            x_try = x + t[..., None] * step
            # the full step is usually accepted: its model Jacobian then serves the next
            # iteration (one equilibrium solve per iteration instead of two)
            f_try, F_try, good, dq_try = evaluate(x_try, with_jacobian=halving == 0, dq0=dq,
                                                  out=F_buf)
            F_buf = None
            if halving == 0:
                F_full = F_try
            ok = ~accepted & good & (np.sum(whitened(Linv, f_try) ** 2, axis=(-2, -1))
                                     <= cost0 * (1 + 1e-8))
            if not batch:
                if ok:
                    x_new, f_new, dq_new = x_try, f_try, dq_try
            else:
                x_new = np.where(ok[..., None], x_try, x_new)
                f_new = np.where(ok[..., None, None], f_try, f_new)
                dq_new = np.where(ok[..., None, None], dq_try, dq_new)
            del f_try, dq_try
            accepted |= ok
            if np.all(accepted):
                break
            t = np.where(accepted, t, 0.5 * t)
        moved = np.max(np.abs(np.where(accepted[..., None], t[..., None] * step, 0.0)), axis=-1)
        x, dq = x_new, dq_new
        if F_full is not None and np.all(accepted & (t == 1.0)):
            f, F = f_new, F_full
        else:
            f, F, _, dq = evaluate(x, dq0=dq)
        del F_full
        # a step no halving can make descend means the cost is at its floor
        converged = (moved <= tol * np.max(np.abs(x), axis=-1)) | ~accepted
        if np.all(converged | ~valid):
            break
    tips.clear()  # the unloaded tool poses (0.13 GB at 1e6 tests) before the last arrays
    if one_campaign:  # the covariances are made again block by block where needed
        cov = PerTestCovariance(noise, J, full(x), measured, w, weights)
        Linv = whitening_per_test(noise, J, full(x), measured, w, weights, out=Linv)
    else:
        cov = covariances_per_test(noise, J, full(x), measured, w, weights)
        Linv = whitening(cov, measured, out=Linv)
    _, cov_x = solve(Linv, F, f, None)
    x = np.where(valid[..., None], x, np.nan)
    cov_x = np.where(valid[..., None, None], cov_x, np.nan)
    return GaussNewtonFit(x=x, F=F, f=f, cov=cov, cov_x=cov_x, iterations=iterations,
                          converged=converged & valid, valid=valid, dq=dq, Linv=Linv)
