"""Weighted Gauss-Newton fit of the exact equilibrium model, batched over campaigns.

Minimises sum_tests r^T Sigma^-1 r, r = d_measured - f(x), over the joint
compliances x, where f is the finite displacement of
:func:`analysis.identification.estimators.exact_model.model_displacement`. The weights Sigma (per
test,
:func:`analysis.identification.noise.residual_covariance`) are re-evaluated at the first
iterates. Each step solves the whitened linearised problem by QR; a step
that raises the cost is halved (per campaign) until it does not.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from analysis.identification.noise import NoiseModel
from analysis.identification.streaming import blocks
from analysis.identification.streaming.systems import Context, systems_for
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
    (:func:`analysis.identification.linalg.lsq.whitening`); R (p + 1, p + 1) the triangular factor
    of the final whitened system [Linv F | Linv r] of one streamed campaign, else None."""

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
    R: np.ndarray | None = None


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
    rows=None,
    values: bool = True,
    w_ref: np.ndarray | None = None,
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
    reweight_iterations : the weights follow x for this many iterations (>= 1),
        then stay fixed so that the last iterations are plain Gauss-Newton.
    weights : (..., m, 6) robust weights > 0 where measured, or None (all 1); see
        :func:`covariances_per_test`. The returned ``cov`` and ``cov_x`` are the weighted ones.
    J : (..., m, 6, 6) the Jacobian at q, if the caller has it (computed otherwise).
    Linv0 : the whitening of the covariances at x0 (:func:`covariances_per_test` then
        :func:`analysis.identification.linalg.lsq.whitening`), if the caller has it: the first
        iteration's weights (it is overwritten by the later ones).
    rows : one campaign of more than :data:`~analysis.identification.streaming.per_test.LAZY_TESTS`
        tests only: a callable given (slice, J, whitening, whitened F, whitened residual)
        of each block of tests in the pass that makes the final system (at the solution and
        its weights), for per-test sums a caller would otherwise make in a pass of its own.
    w_ref : (..., m, 6) the reference readings' wrench (preloads; ``w`` is then the
        difference, see ``exact_model.model_displacement_state``), or None. Not with a
        streamed campaign.
    values : one streamed campaign only: False leaves ``f`` None (48 MB at 1e6 tests not
        held; the caller takes the values from the result's ``F``, which makes them with
        each block,
        :meth:`~analysis.identification.streaming.per_test.PerTestModelJacobian.values`).

    One campaign of more than ``LAZY_TESTS`` tests is fitted without holding F or the
    whitening (:class:`~analysis.identification.streaming.systems.StreamedSystems`); the
    result's ``F``, ``cov`` and ``Linv`` are
    then made when sliced, and ``R`` is the triangular factor of the final whitened
    system [Linv F | Linv r].
    """
    cols = list(joints)
    dz = np.where(measured, d, 0.0)
    J = jacobian(robot, q) if J is None else J
    batch = q.shape[:-2]
    ctx = Context(robot, q, w, dz, measured, cols, noise, J, weights, batch, {}, w_ref)
    systems = systems_for(q.shape[-2], batch)(ctx)

    x = np.array(x0, dtype=float)
    valid = np.all(np.isfinite(x), axis=-1)
    x = np.where(valid[..., None], x, 0.0)
    wx = x  # the weights of the first iteration
    state = systems.evaluate(x, True, None, False, wx)
    valid &= state.ok
    one_campaign = (state.F is not None and state.F.ndim == 3
                    and state.F.shape[0] > blocks.EVAL_BLOCK)
    converged = np.zeros(batch, dtype=bool)
    iterations = 0
    for iterations in range(1, max_iter + 1):  # noqa: B007 (count kept after the loop)
        if iterations <= reweight_iterations:
            wx = x
            systems.weigh(x, Linv0 if iterations == 1 else None)
        step, _, cost0 = systems.solve(state, valid)
        step = np.where(valid[..., None] & np.isfinite(step), step, 0.0)
        if iterations > 1:
            # a step below the tolerance is not taken: x is then within tol * max |x| of the
            # minimum, and its model, Jacobian and deflections are already evaluated (one
            # equilibrium solve saved, ~1/4 of the fit)
            small = np.max(np.abs(step), axis=-1) <= tol * np.max(np.abs(x), axis=-1)
            if np.all(small | ~valid):
                converged = small
                break

        follow = iterations + 1 <= reweight_iterations  # the next weights at the next x?
        x, state, moved, accepted = _descend(systems, x, step, state, cost0, wx, follow,
                                             one_campaign)
        # a step no halving can make descend means the cost is at its floor
        converged = (moved <= tol * np.max(np.abs(x), axis=-1)) | ~accepted
        if np.all(converged | ~valid):
            break
    ctx.tips.clear()  # the unloaded tool poses (0.13 GB at 1e6 tests) before the last arrays
    cov, Linv, cov_x, F, R, f, dq = systems.final(x, state, valid, rows, values)
    x = np.where(valid[..., None], x, np.nan)
    cov_x = np.where(valid[..., None, None], cov_x, np.nan)
    return GaussNewtonFit(x=x, F=F, f=f, cov=cov, cov_x=cov_x, iterations=iterations,
                          converged=converged & valid, valid=valid, dq=dq, Linv=Linv, R=R)


def _descend(systems, x, step, state, cost0, wx, follow: bool, one_campaign: bool):
    """(x, state, moved, accepted): one Gauss-Newton step from x, halved campaign by
    campaign (up to 12 times) until the cost under the current weights does not rise
    above ``cost0``; the state (model, Jacobian, deflections) at the new x, whitened at
    the new x when the weights ``follow`` it, else at ``wx``; ``moved`` (...) the largest
    step taken, ``accepted`` (...) where some step descended."""
    ctx = systems.c
    batch = ctx.batch
    # the next model Jacobian comes with the step's evaluation, into F's array
    F_buf = state.F if one_campaign else None
    dq = state.dq
    t = np.ones(batch)
    accepted = np.zeros(batch, dtype=bool)
    # one campaign: the accepted trial is taken as it is (no (m, 6) copies: ``ok`` is
    # one bool), else merged campaign by campaign
    x_new, f_new, dq_new = (x, state.f, dq) if not batch else (
        x.copy(), state.f.copy(), dq.copy())
    state = None
    full = None
    for halving in range(12):
        x_try = x + t[..., None] * step
        # the full step is usually accepted: its model Jacobian then serves the next
        # iteration (one equilibrium solve per iteration instead of two)
        # Newton starts from the deflections at x scaled joint by joint to x_try (the
        # first-order deflection is proportional to the compliance): ~2.2 Newton
        # evaluations per test instead of 3 for a step of 10 %
        with np.errstate(divide="ignore", invalid="ignore"):
            xf, xt = ctx.full(x), ctx.full(x_try)
            dq_scale = np.where((xf != 0) & np.isfinite(xt / xf), xt / xf, 1.0)
        trial = systems.evaluate(x_try, halving == 0, dq, True, x_try if follow else wx,
                                 dq_scale=dq_scale,
                                 out=F_buf)
        F_buf = None
        if halving == 0:
            full = trial
        ok = ~accepted & trial.ok & (trial.cost <= cost0 * (1 + 1e-8))
        if not batch:
            if ok:
                x_new, f_new, dq_new = x_try, trial.f, trial.dq
        else:
            x_new = np.where(ok[..., None], x_try, x_new)
            f_new = np.where(ok[..., None, None], trial.f, f_new)
            dq_new = np.where(ok[..., None, None], trial.dq, dq_new)
        del trial
        accepted |= ok
        if np.all(accepted):
            break
        t = np.where(accepted, t, 0.5 * t)
    moved = np.max(np.abs(np.where(accepted[..., None], t[..., None] * step, 0.0)), axis=-1)
    if full is not None and np.all(accepted & (t == 1.0)):
        state = replace(full, f=f_new, dq=dq_new)
    else:
        state = systems.evaluate(x_new, True, dq_new, False, x_new if follow else wx)
    return x_new, state, moved, accepted
