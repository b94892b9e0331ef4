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

from dataclasses import dataclass

import numpy as np

from analysis.identification.estimators.exact_model import model_displacement_state
from analysis.identification.linalg import lsq
from analysis.identification.linalg.lsq import (
    qr_solve,
    stack_matrix,
    stack_vector,
    whitened_lstsq,
    whitening,
)
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.streaming.per_test import (
    PerTestBlocks,
    PerTestModelJacobian,
    PerTestWhitening,
)
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


#: tests per block when one campaign's model is evaluated: the equilibrium's working
#: arrays then stay in cache (measured on 1e5 KR240-2 tests, warm start with the model
#: Jacobian: 2.0-2.2 us/test in blocks of 4096, 2.7-3.4 in blocks of 8192; 41 us/test as
#: one block of 1e5 before the entry-major kernels)
EVAL_BLOCK = 4096


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
    (:mod:`analysis.identification.estimators.irls`); component i's variance is divided by
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


class PerTestCovariance(PerTestBlocks):
    """The residual covariance of each test (m, 6, 6) of one large campaign, made when sliced.

    ``cov[s:e]`` is :func:`covariances_per_test` of those tests (the same numbers as a
    slice of the whole array); the (m, 6, 6) array (0.3 GB at 1e6 tests) is never held.
    The passes over it (:func:`analysis.identification.linalg.lsq.sandwich_and_residual_variance`,
    the chi-square's whitening, :func:`~analysis.identification.linalg.lsq.per_test_diagonal`)
    take it by blocks of consecutive tests. ``J`` (m, 6, 6) is the Jacobian at the tests'
    joint angles, ``x_full`` (6,) the compliances the covariances are evaluated at.
    """

    def __init__(self, noise, J, x_full, measured, w=None, weights=None) -> None:
        self.noise, self.J, self.measured, self.w, self.weights = noise, J, measured, w, weights
        self.x_full = np.array(x_full, dtype=float)
        self.shape = J.shape[:-1] + (6,)

    def _make(self, start, stop):
        return self.take(slice(start, stop))

    def take(self, rows) -> np.ndarray:
        """The covariances of the tests ``rows`` (a slice or integer indices)."""
        def part(a):
            return None if a is None else a[rows]

        J = self.J[rows] if isinstance(rows, slice) or not isinstance(self.J, PerTestBlocks) \
            else self.J.take(rows)
        return covariances_per_test(self.noise, J, self.x_full, self.measured[rows],
                                    part(self.w), part(self.weights))


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
    if isinstance(J, PerTestBlocks):  # a large campaign: made when sliced, like J
        return PerTestWhitening(PerTestCovariance(noise, J, x_full, measured, w, weights),
                                measured)
    out = np.empty(J.shape[:-1] + (6,)) if out is None or out.shape != J.shape[:-1] + (6,) \
        else out
    for s in range(0, J.shape[0], EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        out[sl] = whitening_per_test(noise, J[sl], x_full, measured[sl],
                                     None if w is None else w[sl],
                                     None if weights is None else weights[sl])
    return out


class _HeldSystems:
    """The linearised systems of :func:`gauss_newton` from held arrays: F (..., m, 6, p)
    and the whitening (..., m, 6, 6) of every test (small campaigns, batches of them)."""

    streamed = False

    def __init__(self, ctx) -> None:
        self.c = ctx
        self.Linv = None

    def evaluate(self, x, with_jacobian, dq0, cost, system_at, out=None, dq_scale=None):
        """The model at x (f, F, ok, dq) and, when ``cost``, the cost under the current
        weights; ``system_at`` is not used (the weights are made by :meth:`weigh`)."""
        c = self.c
        if dq0 is not None and dq_scale is not None:
            dq0 = dq0 * dq_scale[..., None, :]
        f, F, ok, dq = _model_in_blocks(c.robot, c.q, c.full(x)[..., None, :], c.w,
                                        with_jacobian, dq0, c.cols, c.measured, out, c.tips)
        value = np.sum(c.whitened(self.Linv, f) ** 2, axis=(-2, -1)) if cost else None
        return _State(f=f, F=F, ok=np.all(ok, axis=-1), dq=dq, cost=value)

    def weigh(self, x, Linv0=None) -> None:
        """The weights at compliances x (the caller's ``Linv0`` if given)."""
        c = self.c
        # the previous iteration's whitening array is overwritten; the covariances are made
        # and whitened block by block (only the final ones are kept)
        self.Linv = Linv0 if Linv0 is not None else whitening_per_test(
            c.noise, c.J, c.full(x), c.measured, c.w, c.weights, out=self.Linv)

    def solve(self, state, valid):
        """Gauss-Newton step, (F^T W F)^-1 and the cost sum r^T W r at ``state``."""
        c = self.c
        F, f, Linv = state.F, state.f, self.Linv
        r = c.whitened(Linv, f)
        if F.ndim == 3 and F.shape[0] * 6 > lsq.TALL_ROWS and np.all(valid):
            # one large campaign: blockwise, without the stacked (6m, p) Linv F
            step, cov_unit = whitened_lstsq(F, np.where(c.measured, c.dz - f, 0.0), Linv)
        else:
            Aw = _defined(stack_matrix(Linv @ F), valid)
            step, cov_unit, _ = qr_solve(Aw, stack_vector(r), with_pinv=False)
        return step, cov_unit, np.sum(r**2, axis=(-2, -1))

    def final(self, x, state, valid):
        """cov, Linv, cov_x and F at the solution x."""
        c = self.c
        one_campaign = state.F.ndim == 3 and state.F.shape[0] > EVAL_BLOCK
        if one_campaign:  # the covariances are made again block by block where needed
            cov = PerTestCovariance(c.noise, c.J, c.full(x), c.measured, c.w, c.weights)
            self.Linv = whitening_per_test(c.noise, c.J, c.full(x), c.measured, c.w,
                                           c.weights, out=self.Linv)
        else:
            cov = covariances_per_test(c.noise, c.J, c.full(x), c.measured, c.w, c.weights)
            self.Linv = whitening(cov, c.measured, out=self.Linv)
        _, cov_x, _ = self.solve(state, valid)
        return cov, self.Linv, cov_x, state.F, None, state.f, state.dq


class _StreamedSystems:
    """The linearised systems of :func:`gauss_newton` for one campaign of more than
    :data:`~analysis.identification.streaming.per_test.LAZY_TESTS` tests, never held.

    Each evaluation of the model is one pass over blocks of tests that also whitens
    them (at ``system_at``) and accumulates the triangular factor R of the whitened
    system ``[Linv F | Linv r]`` (:class:`~analysis.identification.linalg.lsq.TallR`): the next
    step comes from R, and the cost r^T W r is the squared norm of R's last column. F
    and the whitening (0.3 GB each at 1e6 tests) exist a block at a time; the same
    numbers as :class:`_HeldSystems` to rounding.
    """

    streamed = True

    def __init__(self, ctx) -> None:
        self.c = ctx
        self.wx = None

    def _whitening(self, x, J, sl):
        c = self.c
        return whitening_per_test(c.noise, J, c.full(x), c.measured[sl], c.w[sl],
                                  None if c.weights is None else c.weights[sl])

    def evaluate(self, x, with_jacobian, dq0, cost, system_at, out=None, dq_scale=None,
                 rows=None,
                 keep_f=False, dq_out=None):
        """The model at x; the cost under the current weights when ``cost``; with the
        Jacobian, R of the system whitened at ``system_at``. ``rows``: a callable given
        (slice, J block, Linv block, whitened F block, whitened residual block) of each
        block (the caller's per-test sums of the same pass). The model values f are kept
        only with ``keep_f`` (the iterations need the deflections alone, their warm
        start); ``dq_out``: an array to write the deflections into (may be ``dq0``)."""
        from analysis.identification.estimators.exact_model import model_displacement_state
        from analysis.model.kinematics import jacobian_from_state

        c = self.c
        m, p = c.q.shape[0], len(c.cols)
        f = np.empty((m, 6)) if keep_f else None
        dq = np.empty(c.q.shape) if dq_out is None else dq_out
        ok = True
        value = 0.0
        acc = lsq.TallR() if with_jacobian else None
        xf = c.full(x)
        same = system_at is not None and cost and np.array_equal(system_at, self.wx)
        for s in range(0, m, EVAL_BLOCK):
            sl = slice(s, s + EVAL_BLOCK)
            unloaded: dict = {}  # J(q) comes from the unloaded chain the model computes
            fb, Fb, okb, dqb = model_displacement_state(
                c.robot, c.q[sl], xf, c.w[sl], with_jacobian,
                None if dq0 is None else dq0[sl] if dq_scale is None else
                dq0[sl] * dq_scale, unloaded=unloaded)
            ok = ok and bool(np.all(okb))
            dq[sl] = dqb
            if keep_f:
                f[sl] = fb
            rb = np.where(c.measured[sl], c.dz[sl] - fb, 0.0)
            Jb = jacobian_from_state(unloaded["state"])
            Lc = None
            if cost:
                Lc = self._whitening(self.wx, Jb, sl)
                value += float(np.sum(np.einsum("mij,mj->mi", Lc, rb) ** 2))
            if with_jacobian:
                Ls = Lc if same else self._whitening(system_at, Jb, sl)
                Fb = Fb[..., c.cols] * c.measured[sl][..., None]
                LF, Lr = Ls @ Fb, np.einsum("mij,mj->mi", Ls, rb)
                acc.add(np.column_stack([LF.reshape(-1, p), Lr.reshape(-1)]))
                if rows is not None:
                    rows(sl, Jb, Ls, LF, Lr)
        R = acc.r() if with_jacobian else None
        return _State(f=f, F=None, ok=np.asarray(ok), dq=dq,
                      cost=np.asarray(value) if cost else None, R=R,
                      system_at=None if system_at is None else np.array(system_at))

    def weigh(self, x, Linv0=None) -> None:
        self.wx = np.array(x, dtype=float)

    def solve(self, state, valid):
        if not np.array_equal(state.system_at, self.wx):  # a logic error, not a data one
            raise RuntimeError("the system was whitened at other weights than the step's")
        return _from_r(state.R)

    def final(self, x, state, valid):
        c = self.c
        xf = c.full(x)
        cov = PerTestCovariance(c.noise, c.J, xf, c.measured, c.w, c.weights)
        self.weigh(x)
        # the model values at the solution come from this pass (the iterations kept only
        # the deflections), which also writes the deflections in place
        last = self.evaluate(x, True, state.dq, False, x, rows=getattr(self, "rows", None),
                             keep_f=getattr(self, "values", True), dq_out=state.dq)
        _, cov_x, _ = _from_r(last.R)
        F = PerTestModelJacobian(c.robot, c.q, c.w, c.measured, c.cols, xf, last.dq)
        return cov, PerTestWhitening(cov, c.measured), cov_x, F, last.R, last.f, last.dq


def _from_r(R):
    """(step, (A^T W A)^-1, r^T W r) from the R (p + 1, p + 1) of [Linv A | Linv r]."""
    from scipy.linalg import solve_triangular

    p = R.shape[0] - 1
    Rinv = solve_triangular(R[:p, :p], np.eye(p))
    return Rinv @ R[:p, p], Rinv @ Rinv.T, float(np.sum(R[:, p] ** 2))


@dataclass
class _State:
    """The model evaluated at one x: f, F (held systems), ok, dq, cost under the current
    weights, R of the whitened system and where it was whitened (streamed systems)."""

    f: np.ndarray
    F: np.ndarray | None
    ok: np.ndarray
    dq: np.ndarray
    cost: np.ndarray | None = None
    R: np.ndarray | None = None
    system_at: np.ndarray | None = None


@dataclass
class _Context:
    """What every evaluation of one :func:`gauss_newton` call shares."""

    robot: RobotModel
    q: np.ndarray
    w: np.ndarray
    dz: np.ndarray
    measured: np.ndarray
    cols: list
    noise: NoiseModel
    J: object
    weights: np.ndarray | None
    batch: tuple
    tips: dict

    def full(self, xp):
        out = np.zeros((*self.batch, 6))
        out[..., self.cols] = xp
        return out

    def whitened(self, Linv, f):
        return np.einsum("...ij,...j->...i", Linv, np.where(self.measured, self.dz - f, 0.0))


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
    values : one streamed campaign only: False leaves ``f`` None (48 MB at 1e6 tests not
        held; the caller takes the values from the result's ``F``, which makes them with
        each block,
        :meth:`~analysis.identification.streaming.per_test.PerTestModelJacobian.values`).

    One campaign of more than ``LAZY_TESTS`` tests is fitted without holding F or the
    whitening (:class:`_StreamedSystems`); the result's ``F``, ``cov`` and ``Linv`` are
    then made when sliced, and ``R`` is the triangular factor of the final whitened
    system [Linv F | Linv r].
    """
    from analysis.identification.streaming import per_test

    cols = list(joints)
    dz = np.where(measured, d, 0.0)
    J = jacobian(robot, q) if J is None else J
    batch = q.shape[:-2]
    ctx = _Context(robot, q, w, dz, measured, cols, noise, J, weights, batch, {})
    streamed = not batch and q.shape[0] > per_test.LAZY_TESTS
    systems = _StreamedSystems(ctx) if streamed else _HeldSystems(ctx)

    x = np.array(x0, dtype=float)
    valid = np.all(np.isfinite(x), axis=-1)
    x = np.where(valid[..., None], x, 0.0)
    wx = x  # the weights of the first iteration
    state = systems.evaluate(x, True, None, False, wx)
    valid &= state.ok
    one_campaign = state.F is not None and state.F.ndim == 3 and state.F.shape[0] > EVAL_BLOCK
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
        x, dq = x_new, dq_new
        if full is not None and np.all(accepted & (t == 1.0)):
            state = full
            state.f, state.dq = f_new, dq
        else:
            state = systems.evaluate(x, True, dq, False, x if follow else wx)
        del full
        # a step no halving can make descend means the cost is at its floor
        converged = (moved <= tol * np.max(np.abs(x), axis=-1)) | ~accepted
        if np.all(converged | ~valid):
            break
    ctx.tips.clear()  # the unloaded tool poses (0.13 GB at 1e6 tests) before the last arrays
    if streamed:
        systems.rows, systems.values = rows, values
    cov, Linv, cov_x, F, R, f, dq = systems.final(x, state, valid)
    x = np.where(valid[..., None], x, np.nan)
    cov_x = np.where(valid[..., None, None], cov_x, np.nan)
    return GaussNewtonFit(x=x, F=F, f=f, cov=cov, cov_x=cov_x, iterations=iterations,
                          converged=converged & valid, valid=valid, dq=dq, Linv=Linv, R=R)
