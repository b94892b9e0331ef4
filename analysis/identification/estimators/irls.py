"""Robust fitting: Huber or Tukey M-estimation by iteratively reweighted least squares.

A glitch (a tracker reading taken while the reflector was occluded, a wrong
line of the CSV) pulls the Gaussian fit towards itself. The M-estimators here
bound its influence instead: each measured component i gets a weight from its
whitened residual

    r_i = (d_i - f_i(x)) / sigma_i,

sigma_i the noise model's standard deviation of that component (displacement
noise plus the wrench noise through the Cartesian compliance at x,
:func:`analysis.identification.noise.residual_covariance`), and the existing
weighted fit (WLS or the exact Gauss-Newton fit of
:mod:`analysis.identification.estimators.fit_solvers`) is repeated with component i's
variance divided by its weight (correlations within a test kept), until the
weights stop changing.

* Huber: w = min(1, c / |r|), c = :data:`HUBER_C` = 1.345;
* Tukey biweight: w = (1 - (r / c)^2)^2 for |r| < c, else 0,
  c = :data:`TUKEY_C` = 4.685; started from the Huber solution, since its
  objective is not convex.

Both constants give 95 % asymptotic efficiency under Gaussian noise.

Around ols and wls the residuals are the exact model's, d - f(x_c) at the
bias-corrected estimate x_c, not the linear model's d - A x: the latter hold the
linear model's deterministic misfit f - A x (at twice the loads of the coverage
study up to 4 sigma of a component, more than the Huber and Tukey constants),
which the weights would treat as glitches. Each iteration fits the linear model
to d - (f(x_c) - A x_c) (the fixed point x_c = G (d - (f(x_c) - A x_c)) is the
corrected estimate of :mod:`analysis.identification.corrections.linear_bias`);
the final fit on the measured d gives the raw estimate that correction starts
from. The sandwich's scores take the same residuals, so the weights and the
covariance describe one estimator.

Scale: 1 on the whitened residuals. The noise figures are those of calibrated
instruments, and they are checked by the chi-square test; a scale estimated
from the data (MAD) would be noisy with a campaign's few dozen residuals and
would absorb a systematic misfit (a wrong tool point) that the checks are
there to catch.

Weights have converged when none changes by more than :data:`WEIGHT_TOL`
between iterations (at most :data:`MAX_ITER`). A zero weight (Tukey) takes
the component out of the fit.

Covariance: the M-estimator sandwich H^-1 B H^-T, its meat each test's score covariance
under the noise model times a scale estimated from that test, and Student t intervals
with per-joint Satterthwaite degrees of freedom
(:mod:`analysis.identification.estimators.robust_covariance`).
``ols`` is the unweighted fit with the robust weights (min sum w e^2), its weights
from the same whitened residuals.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from analysis.choices import METHODS, REWEIGHTING_MODES, ROBUST_MODES
from analysis.errors import InputError
from analysis.identification.corrections.wrench_eiv import wrench_eiv_matrix
from analysis.identification.estimators.fit_record import Fit
from analysis.identification.estimators.fit_solvers import (
    _covariances,
    _full,
    _linear_estimator,
    _wrench_eiv,
    fit_exact,
    fit_linear,
)
from analysis.identification.estimators.linear_model import tests_design
from analysis.identification.estimators.robust_covariance import (
    RobustCovariance,
    robust_covariance,
)
from analysis.identification.io.columns import COMPONENTS
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.sandwich import sandwich
from analysis.identification.streaming.per_test import apply

ROBUST_METHODS = ROBUST_MODES
#: Huber's tuning constant (95 % efficiency under Gaussian noise)
HUBER_C = 1.345
#: Tukey's biweight tuning constant (95 % efficiency under Gaussian noise)
TUKEY_C = 4.685
#: the weights have converged when none changes by more than this between iterations
WEIGHT_TOL = 1e-6
#: iterations of reweighting after which the weights must be visibly contracting
MAX_ITER = 50
#: beyond MAX_ITER the reweighting goes on while the largest weight change shrinks by at
#: least SLOW_FACTOR over every SLOW_SPAN iterations (a rate of 0.933 per iteration or
#: faster: IRLS converges linearly, at 2x the loads with rates up to ~0.85 measured), up
#: to ITER_CAP iterations; otherwise it is refused (weights that do not contract: the
#: data hold competing explanations)
SLOW_SPAN = 10
SLOW_FACTOR = 0.5
ITER_CAP = 500
#: a row is reported as down-weighted below this weight (Gaussian data: Huber ~0.7 %, Tukey
#: ~1.1 % of the rows, |r| > 2.69 resp. 2.53)
REPORT_BELOW = 0.5


def huber_weight(r: np.ndarray, c: float = HUBER_C) -> np.ndarray:
    """Huber weights min(1, c/|r|) of whitened residuals r (any shape)."""
    a = np.abs(r)
    return np.where(a <= c, 1.0, c / np.where(a > 0, a, 1.0))


def tukey_weight(r: np.ndarray, c: float = TUKEY_C) -> np.ndarray:
    """Tukey biweights (1 - (r/c)^2)^2 for |r| < c, else 0, of whitened residuals r."""
    u = np.asarray(r, dtype=float) / c
    return np.where(np.abs(u) < 1.0, (1.0 - u**2) ** 2, 0.0)


@dataclass(frozen=True)
class DownWeighted:
    """One measured component the robust fit down-weighted (weight < REPORT_BELOW)."""

    test: int  # 0-based test index
    line: int  # CSV line
    pose: str
    component: str
    weight: float
    whitened_residual: float  # r = residual / sigma at the robust solution


@dataclass(frozen=True)
class _SandwichInputs:
    """What :func:`robust_covariance` needs of a converged robust fit: the model's Jacobian
    A (m, 6, p), the unweighted noise covariance (m, 6, 6), the residuals (m, 6) (m, rad)
    the weights were taken from (d - f(x); ols, wls: d - f(x_c), x_c the bias-corrected
    estimate; 0 where not kept), the components kept (weight > 0), whether the fit is
    weighted by the noise model (wls, exact), the errors-in-variables S (p, p) or None and
    the fixed-weight covariance (p, p)."""

    A: np.ndarray
    cov: np.ndarray
    residual: np.ndarray
    kept: np.ndarray
    weighted: bool
    S: np.ndarray | None
    fixed: np.ndarray


@dataclass(frozen=True)
class RobustFit:
    """A robust fit: ``fit`` (its ``cov`` the unweighted noise covariance, ``G`` the weighted
    estimator), weights (m, 6) (1 where not measured), whitened residuals (m, 6) at the
    solution (NaN where not measured), iterations of reweighting (Huber + Tukey),
    and the components reported as down-weighted."""

    method: str
    constant: float
    fit: Fit
    weights: np.ndarray
    whitened: np.ndarray
    iterations: int
    down_weighted: tuple[DownWeighted, ...]
    inputs: _SandwichInputs | None = None
    covariance: RobustCovariance | None = None

    def with_covariance(self) -> RobustFit:
        """This fit with its sandwich covariance made
        (:mod:`analysis.identification.estimators.robust_covariance`), its scores on the
        residuals the weights were taken from (:func:`_irls`): d - f(x) of the exact fit;
        for ols and wls the exact model's d - f(x_c) at the bias-corrected estimate, free
        of the linear model's deterministic misfit, which is no noise and in the tests'
        scores would count as variance."""
        i = self.inputs
        return replace(self, covariance=robust_covariance(
            i.A, i.cov, i.residual, i.kept, self.method, self.constant, weighted=i.weighted,
            fixed=i.fixed, S=i.S))

    def kept(self, measured: np.ndarray) -> np.ndarray:
        """(m, 6) bool: measured components not reported as down-weighted."""
        return measured & (self.weights >= REPORT_BELOW)

    def describe(self) -> dict:
        """JSON-ready summary for results.json (``robust`` key)."""
        return {
            "method": self.method,
            "constant": self.constant,
            "scale": "1 on residuals whitened by the noise model's sigma (known noise)",
            "iterations": self.iterations,
            "weight_tolerance": WEIGHT_TOL,
            "reported_below_weight": REPORT_BELOW,
            "covariance": None if self.covariance is None else self.covariance.describe(),
            "down_weighted": [
                {"test": d.test + 1, "line": d.line, "pose": d.pose, "component": d.component,
                 "weight": d.weight, "whitened_residual": d.whitened_residual}
                for d in self.down_weighted
            ],
        }

    def summary(self) -> str:
        """One line for the terminal: the method and the rows down-weighted."""
        head = (f"robust fit ({self.method}, c = {self.constant:g}, scale 1 on whitened "
                f"residuals, {self.iterations} reweighting iterations)")
        if not self.down_weighted:
            return f"{head}: no component down-weighted below {REPORT_BELOW:g}"
        rows = ", ".join(f"test {d.test + 1} line {d.line} (pose {d.pose}) {d.component} "
                         f"weight {d.weight:.3g} (r = {d.whitened_residual:.1f})"
                         for d in self.down_weighted)
        return (f"{head}: {len(self.down_weighted)} component(s) down-weighted below "
                f"{REPORT_BELOW:g}: {rows}")


def _sigma(noise, J, x_p, tests: TestArrays, joints) -> np.ndarray:
    """(m, 6) the noise model's sigma of each residual component at compliances x_p."""
    cov = _covariances(noise, J, _full(x_p, joints), tests.measured, tests.w)
    return np.sqrt(np.diagonal(cov, axis1=-2, axis2=-1))


def _weighted_fit(robot, tests: TestArrays, joints, noise, method, weights, start,
                  J) -> Fit:
    """One fit by ``method`` with ``weights`` (zero weights leave the fit); ``J``: the
    tests' Jacobians (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`)."""
    keep = tests.measured & (weights > 0)
    sub = TestArrays(tests.pose, tests.q, tests.w, np.where(keep, tests.d, np.nan), keep,
                     tests.line)
    if int(keep.sum()) < len(joints):
        raise InputError(f"the robust fit kept {int(keep.sum())} components for {len(joints)} "
                         "unknown joint compliances; too many glitches to identify from",
                         where="--robust")
    w = np.where(keep, weights, 1.0)
    if method == "exact":
        return fit_exact(robot, sub, joints, noise, start=start, weights=w, J=J)
    if method == "ols":
        return _weighted_ols(robot, sub, joints, noise, w, J)
    return fit_linear(robot, sub, joints, noise, weighted=True, weights=w, start=start, J=J)


def _weighted_ols(robot, sub: TestArrays, joints, noise, w, J) -> Fit:
    """The unweighted (OLS) fit of the linear model with robust weights ``w`` (m, 6) on the
    components ``sub.measured``: min sum w e^2, i.e. W = diag(w), Linv = diag(sqrt w);
    corrected for the wrench noise in the regressor with that W, as OLS is. ``cov`` is the
    unweighted noise covariance."""
    J, A = tests_design(robot, sub, joints, J)
    Linv = np.sqrt(np.where(sub.measured, w, 0.0))[..., :, None] * np.eye(6)
    x, bread, Linv = _linear_estimator(A, sub.d, sub.measured, None, weighted=True, Linv=Linv)
    x, bread, shift = _wrench_eiv(noise, J, sub, joints, x, bread, Linv)
    cov = _covariances(noise, J, _full(x, joints), sub.measured, sub.w)
    return Fit(x=x, A=A, cov=cov, predicted=apply(A, x), iterations=0, bread=bread, Linv=Linv,
               eiv_shift=shift)


def _model(robot, tests, joints, method, x_p, J, A_lin):
    """(m, 6) prediction and (m, 6, p) model Jacobian at x_p for every measured component."""
    if method == "exact":
        from analysis.identification.estimators.exact_model import model_displacement

        f, F = model_displacement(robot, tests.q, _full(x_p, joints)[None, :], tests.w,
                                  w_ref=tests.w_ref)
        return f, F[..., list(joints)] * tests.measured[..., None]
    return apply(A_lin, x_p), A_lin


def _exact_prediction(robot, tests: TestArrays, joints, x_p) -> np.ndarray | None:
    """(m, 6) the exact model's displacement f(x_p) (m, rad), 0 where not measured, made in
    blocks of :data:`~analysis.identification.streaming.blocks.EVAL_BLOCK` tests; None
    where the equilibrium cannot be solved at x_p for some test."""
    from analysis.identification.estimators.exact_model import model_displacement_masked
    from analysis.identification.streaming.blocks import EVAL_BLOCK

    x_full = _full(x_p, joints)
    out = np.zeros(tests.measured.shape)
    for s in range(0, tests.m, EVAL_BLOCK):
        sl = slice(s, s + EVAL_BLOCK)
        f, _, ok = model_displacement_masked(robot, tests.q[sl], x_full, tests.w[sl],
                                             with_jacobian=False,
                                             w_ref=None if tests.w_ref is None else tests.w_ref[sl])
        if not np.all(ok):
            return None
        out[sl] = np.where(tests.measured[sl], f, 0.0)
    return out


def _with_data(tests: TestArrays, d: np.ndarray) -> TestArrays:
    """``tests`` with the displacements ``d`` (m, 6) (m, rad) instead of the measured ones."""
    return TestArrays(tests.pose, tests.q, tests.w, np.where(tests.measured, d, np.nan),
                      tests.measured, tests.line)


def _irls(robot, tests, joints, noise, method, weight_fn, c, x, weights, J, A_lin, misfit):
    """Reweight until the weights (and, for the linear fits, their misfit) move by <=
    WEIGHT_TOL; returns x, weights, r, iterations, the (m, 6) prediction the residuals r are
    taken from, and the misfit.

    ``misfit`` (m, 6) (m, rad): for ols and wls the linear model's deterministic misfit
    f(x) - A x at the current estimate (zeros to start, None for exact): the linear fit is
    made on d - misfit, so that x is the bias-corrected estimate x_c (x_c = G (d - (f(x_c)
    - A x_c)), :mod:`analysis.identification.corrections.linear_bias`) and the weights come
    from the exact model's residuals d - f(x_c), the noise, not from the linear residuals
    d - A x_hat, which hold the misfit (at twice the loads of the coverage study up to 4
    sigma: clean components down-weighted as glitches). Where the equilibrium cannot be
    solved, the linear residuals are used (the correction is then unreliable and the
    result refused, :mod:`analysis.identification.checks.plausibility`).

    Refused beyond :data:`MAX_ITER` iterations unless the changes contract (SLOW_FACTOR
    over SLOW_SPAN iterations), and at :data:`ITER_CAP`.
    """
    history: list[float] = []
    for it in range(1, ITER_CAP + 1):
        data = tests if misfit is None else _with_data(tests, tests.d - misfit)
        f = _weighted_fit(robot, data, joints, noise, method, weights, x, J)
        x = f.x
        sigma = _sigma(noise, J, x, tests, joints)
        misfit_moved = 0.0
        if misfit is None:
            pred, _ = _model(robot, tests, joints, method, x, J, A_lin)
        else:
            linear = apply(A_lin, x)
            exact = _exact_prediction(robot, tests, joints, x)
            pred = linear if exact is None else exact
            new_misfit = pred - linear
            misfit_moved = float(np.max(np.abs(new_misfit - misfit)[tests.measured]
                                        / sigma[tests.measured]))
            misfit = new_misfit
        r = np.where(tests.measured, (tests.d - pred) / sigma, np.nan)
        new = np.where(tests.measured, weight_fn(np.nan_to_num(r), c), 1.0)
        moved = np.abs(new - weights)
        weights = new
        change = max(float(np.max(moved)), misfit_moved)
        if change <= WEIGHT_TOL:
            return x, weights, r, it, pred, misfit
        history.append(change)
        if it >= MAX_ITER and change > SLOW_FACTOR * history[-1 - SLOW_SPAN]:
            break
    i, j = np.unravel_index(int(np.argmax(moved)), weights.shape)
    raise InputError(
        f"the robust fit did not settle in {it} reweighting iterations (weights still "
        f"change by {change:.2g}, e.g. line {tests.line[i]} {COMPONENTS[j]}; after "
        f"{MAX_ITER} they must shrink by {1 / SLOW_FACTOR:g}x every {SLOW_SPAN}); the data "
        "hold competing explanations: inspect the residuals or use --robust huber",
        where="--robust")


def robust_fit(robot, tests: TestArrays, joints: tuple[int, ...], noise, method: str,
               robust: str, start: np.ndarray, J=None) -> RobustFit:
    """Huber or Tukey IRLS around the fit ``method`` (ols, wls or exact) from ``start`` (p,).

    See the module docstring for the weights, the scale and the covariance. ``J``: the
    tests' Jacobians (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`) if
    the caller has them.
    """
    if robust not in REWEIGHTING_MODES:
        raise InputError(f"unknown robust estimator {robust!r}: expected one of "
                         f"{', '.join(ROBUST_METHODS)}", where="--robust")
    if method not in METHODS:
        raise InputError(f"unknown method {method!r} for a robust fit", where="--method")
    J, A_lin = tests_design(robot, tests, joints, J)
    ones = np.ones(tests.measured.shape)
    misfit = None if method == "exact" else np.zeros(tests.measured.shape)
    x, weights, r, n_it, scored, misfit = _irls(
        robot, tests, joints, noise, method, huber_weight, HUBER_C,
        np.asarray(start, dtype=float), ones, J, A_lin, misfit)
    c = HUBER_C
    if robust == "tukey":
        c = TUKEY_C
        start_w = np.where(tests.measured, tukey_weight(np.nan_to_num(r), c), 1.0)
        x, weights, r, more, scored, misfit = _irls(
            robot, tests, joints, noise, method, tukey_weight, c, x, start_w, J, A_lin, misfit)
        n_it += more
    # the final fit at the converged weights, on the measured d: its x is the raw linear
    # estimate (corrected for the linearisation bias after, as the Gaussian fit's), its G
    # the weighted estimator
    final = _weighted_fit(robot, tests, joints, noise, method, weights, x, J)
    # G's columns of components with weight 0 are zero: they do not enter x
    pred, A = _model(robot, tests, joints, method, final.x, J, A_lin)
    if method == "exact":
        scored = pred
    cov = _covariances(noise, J, _full(final.x, joints), tests.measured, tests.w)
    # G = final.bread A^T W_weighted, kept factored (memory linear in the tests)
    fit = Fit(x=final.x, A=A, cov=cov, predicted=pred, iterations=n_it, bread=final.bread,
              Linv=final.Linv, eiv_shift=final.eiv_shift)
    keep = tests.measured & (weights > 0)
    S = None if final.eiv_shift is None else wrench_eiv_matrix(
        J, noise.wrench_sigma_at(tests.w) ** 2, final.Linv, keep, cols=list(joints))
    inputs = _SandwichInputs(A=A, cov=cov, residual=np.where(keep, tests.d - scored, 0.0),
                             kept=keep, weighted=method != "ols", S=S,
                             fixed=sandwich(A, cov, final.bread, final.Linv))
    down = tuple(
        DownWeighted(test=int(i), line=int(tests.line[i]), pose=str(tests.pose[i]),
                     component=COMPONENTS[j], weight=float(weights[i, j]),
                     whitened_residual=float(r[i, j]))
        for i, j in zip(*np.nonzero(tests.measured & (weights < REPORT_BELOW)), strict=True))
    return RobustFit(method=robust, constant=c, fit=fit, weights=weights, whitened=r,
                     iterations=n_it, down_weighted=down, inputs=inputs)

