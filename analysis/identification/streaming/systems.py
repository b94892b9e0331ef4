"""The linearised systems of a Gauss-Newton fit, behind one interface for any size.

:class:`LinearisedSystems` is what
:func:`~analysis.identification.estimators.gauss_newton.gauss_newton` asks of the systems
it solves, whatever the campaign's size: :meth:`~LinearisedSystems.evaluate` the model
(and its Jacobian) at x, :meth:`~LinearisedSystems.weigh` (the weights at x),
:meth:`~LinearisedSystems.solve` (the step) and :meth:`~LinearisedSystems.final` (the
covariances at the solution); and what the identification's stages ask of a fit made on
them, :meth:`~LinearisedSystems.statistics` (its covariance, residual variances and
chi-square). :class:`HeldSystems` holds F and the whitening of every
test (small campaigns, batches of them); :class:`StreamedSystems` never holds them (one
campaign of more than :data:`~analysis.identification.streaming.per_test.LAZY_TESTS`
tests): the same numbers to rounding.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from analysis.identification.linalg import lsq
from analysis.identification.linalg.lsq import solve_blocks, whitening
from analysis.identification.noise import NoiseModel
from analysis.identification.streaming import blocks, per_test
from analysis.identification.streaming.blocks import model_in_blocks
from analysis.identification.streaming.covariances import (
    PerTestCovariance,
    covariances_per_test,
    whitening_per_test,
)
from analysis.identification.streaming.per_test import PerTestModelJacobian, PerTestWhitening
from analysis.model.robot_model import RobotModel


class LinearisedSystems(ABC):
    """The systems of one :func:`gauss_newton` call; ``streamed``: never held.

    The implementation (:func:`systems_for`) also answers what the estimators and the
    statistics do differently at a campaign's size, so that they never ask for it:
    ``compares_wls``: the exact fit also makes the WLS fit for results.json's comparison;
    :meth:`final_pass_sums`: the per-test sums made in the pass that forms the final
    system; :meth:`statistics`: how a fit's statistics are made.
    """

    streamed: bool
    compares_wls: bool

    @classmethod
    def final_pass_sums(cls, problem):
        """What the final pass also sums for ``problem`` (an
        :class:`~analysis.identification.problem.IdentificationProblem`): None, or the
        errors-in-variables S and the validation's per-fold sums
        (:class:`~analysis.identification.streaming.fold_sums.FinalPassSums`)."""
        return None

    @classmethod
    def statistics(cls, problem, outcome):
        """(statistics, outcome): the
        :class:`~analysis.identification.statistics.FitStatistics` of ``outcome`` (an
        :class:`~analysis.identification.estimators.base.EstimatorFit` of ``problem``) and
        the outcome the later stages use: here from a pass over the fit's blocks of its
        own (:func:`~analysis.identification.statistics.held_statistics`), the outcome as
        it is."""
        from analysis.identification.statistics import held_statistics

        return held_statistics(problem, outcome), outcome

    @abstractmethod
    def evaluate(self, x, with_jacobian, dq0, cost, system_at, out=None, dq_scale=None):
        """The model at x (:class:`State`), the cost under the current weights when
        ``cost``, the system whitened at ``system_at`` when ``with_jacobian``."""

    @abstractmethod
    def weigh(self, x, Linv0=None) -> None:
        """Set the weights at compliances x (the caller's whitening ``Linv0`` if given)."""

    @abstractmethod
    def solve(self, state, valid):
        """(step, (F^T W F)^-1, r^T W r) at ``state``."""

    @abstractmethod
    def final(self, x, state, valid, rows=None, values: bool = True):
        """(cov, Linv, cov_x, F, R, f, dq) at the solution x; ``rows`` and ``values``: see
        :func:`~analysis.identification.estimators.gauss_newton.gauss_newton` (systems
        that do not stream refuse ``rows``: they make no final pass)."""


class HeldSystems(LinearisedSystems):
    """The linearised systems of :func:`gauss_newton` from held arrays: F (..., m, 6, p)
    and the whitening (..., m, 6, 6) of every test (small campaigns, batches of them)."""

    streamed = False
    compares_wls = True

    def __init__(self, ctx) -> None:
        self.c = ctx
        self.Linv = None

    def evaluate(self, x, with_jacobian, dq0, cost, system_at, out=None, dq_scale=None):
        """The model at x (f, F, ok, dq) and, when ``cost``, the cost under the current
        weights; ``system_at`` is not used (the weights are made by :meth:`weigh`)."""
        c = self.c
        if dq0 is not None and dq_scale is not None:
            dq0 = dq0 * dq_scale[..., None, :]
        f, F, ok, dq = model_in_blocks(c.robot, c.q, c.full(x)[..., None, :], c.w,
                                        with_jacobian, dq0, c.cols, c.measured, out, c.tips,
                                        w_ref=c.w_ref)
        value = np.sum(c.whitened(self.Linv, f) ** 2, axis=(-2, -1)) if cost else None
        return State(f=f, F=F, ok=np.all(ok, axis=-1), dq=dq, cost=value)

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
        rhs = np.where(c.measured, c.dz - state.f, 0.0)
        r = np.einsum("...ij,...j->...i", self.Linv, rhs)  # whitened (the cost's residuals)
        step, cov_unit = solve_blocks(state.F, rhs, self.Linv, valid, Lr=r)
        return step, cov_unit, np.sum(r**2, axis=(-2, -1))

    def final(self, x, state, valid, rows=None, values: bool = True):
        """cov, Linv, cov_x and F at the solution x (f always kept: ``values`` unused)."""
        if rows is not None:  # a logic error: the sums' owner would get nothing
            raise ValueError("held systems make no final pass for per-test sums")
        c = self.c
        one_campaign = state.F.ndim == 3 and state.F.shape[0] > blocks.EVAL_BLOCK
        if one_campaign:  # the covariances are made again block by block where needed
            cov = PerTestCovariance(c.noise, c.J, c.full(x), c.measured, c.w, c.weights)
            self.Linv = whitening_per_test(c.noise, c.J, c.full(x), c.measured, c.w,
                                           c.weights, out=self.Linv)
        else:
            cov = covariances_per_test(c.noise, c.J, c.full(x), c.measured, c.w, c.weights)
            self.Linv = whitening(cov, c.measured, out=self.Linv)
        _, cov_x, _ = self.solve(state, valid)
        return cov, self.Linv, cov_x, state.F, None, state.f, state.dq


class StreamedSystems(LinearisedSystems):
    """The linearised systems of :func:`gauss_newton` for one campaign of more than
    :data:`~analysis.identification.streaming.per_test.LAZY_TESTS` tests, never held.

    Each evaluation of the model is one pass over blocks of tests that also whitens
    them (at ``system_at``) and accumulates the triangular factor R of the whitened
    system ``[Linv F | Linv r]`` (:class:`~analysis.identification.linalg.lsq.TallR`): the next
    step comes from R, and the cost r^T W r is the squared norm of R's last column. F
    and the whitening (0.3 GB each at 1e6 tests) exist a block at a time; the same
    numbers as :class:`HeldSystems` to rounding.
    """

    streamed = True
    compares_wls = False  # two passes over every test for a comparison only

    @classmethod
    def final_pass_sums(cls, problem):
        """The errors-in-variables S and the validation's per-fold sums (when validating
        over at least 3 folds) made in the final pass: no pass of their own."""
        from analysis.identification.streaming.fold_sums import FinalPassSums

        fold = problem.folds
        n_folds = int(fold.max(initial=-1)) + 1
        return FinalPassSums(problem.tests, problem.joints, problem.noise,
                             fold if problem.options.validate and n_folds >= 3 else None,
                             n_folds)

    @classmethod
    def statistics(cls, problem, outcome):
        """A fit made by these systems' final pass (the Gaussian exact fit: it carries
        that pass's R, whitened by its own covariances) from R, in one pass that also
        makes the prediction the fit deferred
        (:func:`~analysis.identification.statistics.final_pass_statistics`); a fit made
        without it (a linear model's, a robust fit) by a pass of its own, as held ones."""
        if outcome.fit.R is None:
            return super().statistics(problem, outcome)
        from analysis.identification.statistics import final_pass_statistics

        return final_pass_statistics(problem, outcome)

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
        for s in range(0, m, blocks.EVAL_BLOCK):
            sl = slice(s, s + blocks.EVAL_BLOCK)
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
        return State(f=f, F=None, ok=np.asarray(ok), dq=dq,
                      cost=np.asarray(value) if cost else None, R=R,
                      system_at=None if system_at is None else np.array(system_at))

    def weigh(self, x, Linv0=None) -> None:
        self.wx = np.array(x, dtype=float)

    def solve(self, state, valid):
        if not np.array_equal(state.system_at, self.wx):  # a logic error, not a data one
            raise RuntimeError("the system was whitened at other weights than the step's")
        return from_r(state.R)

    def final(self, x, state, valid, rows=None, values: bool = True):
        c = self.c
        xf = c.full(x)
        cov = PerTestCovariance(c.noise, c.J, xf, c.measured, c.w, c.weights)
        self.weigh(x)
        # the model values at the solution come from this pass (the iterations kept only
        # the deflections), which also writes the deflections in place
        last = self.evaluate(x, True, state.dq, False, x, rows=rows, keep_f=values,
                             dq_out=state.dq)
        _, cov_x, _ = from_r(last.R)
        F = PerTestModelJacobian(c.robot, c.q, c.w, c.measured, c.cols, xf, last.dq)
        return cov, PerTestWhitening(cov, c.measured), cov_x, F, last.R, last.f, last.dq


def systems_for(m: int, batch: tuple[int, ...] = ()) -> type[LinearisedSystems]:
    """The systems of a fit of ``m`` tests (a batch of campaigns of shape ``batch``):
    :class:`StreamedSystems` for one campaign whose blocks are made when sliced
    (:func:`~analysis.identification.streaming.per_test.streamed`), else
    :class:`HeldSystems`."""
    return StreamedSystems if per_test.streamed(m, batch) else HeldSystems


def from_r(R):
    """(step, (A^T W A)^-1, r^T W r) from the R (p + 1, p + 1) of [Linv A | Linv r]."""
    from scipy.linalg import solve_triangular

    p = R.shape[0] - 1
    Rinv = solve_triangular(R[:p, :p], np.eye(p))
    return Rinv @ R[:p, p], Rinv @ Rinv.T, float(np.sum(R[:, p] ** 2))


@dataclass
class State:
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
class Context:
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
    #: the reference readings' wrench (preloads), or None; held systems only
    w_ref: np.ndarray | None = None

    def full(self, xp):
        out = np.zeros((*self.batch, 6))
        out[..., self.cols] = xp
        return out

    def whitened(self, Linv, f):
        return np.einsum("...ij,...j->...i", Linv, np.where(self.measured, self.dz - f, 0.0))
