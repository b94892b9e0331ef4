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
:mod:`analysis.identification.estimators.fitting`) is repeated with component i's
variance divided by its weight (correlations within a test kept), until the
weights stop changing.

* Huber: w = min(1, c / |r|), c = :data:`HUBER_C` = 1.345;
* Tukey biweight: w = (1 - (r / c)^2)^2 for |r| < c, else 0,
  c = :data:`TUKEY_C` = 4.685; started from the Huber solution, since its
  objective is not convex.

Both constants give 95 % asymptotic efficiency under Gaussian noise.

Scale: 1 on the whitened residuals. The noise figures are those of calibrated
instruments, and they are checked by the chi-square test; a scale estimated
from the data (MAD) would be noisy with a campaign's few dozen residuals and
would absorb a systematic misfit (a wrong tool point) that the checks are
there to catch.

Weights have converged when none changes by more than :data:`WEIGHT_TOL`
between iterations (at most :data:`MAX_ITER`). A zero weight (Tukey) takes
the component out of the fit.

Covariance: the weighted fit's, with the final weights held fixed, in the
sandwich form ``cov_x = G Sigma G^T``, G the (linearised) weighted estimator
and Sigma the noise model's unweighted covariance. It leaves out the
dependence of the weights on the data (the M-estimator sandwich's psi'
terms); under Gaussian noise this understates the variance by about the
efficiency loss, a few per cent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from analysis.errors import InputError
from analysis.identification.estimators.fit import Fit
from analysis.identification.estimators.fitting import _covariances, _full, fit_exact, fit_linear
from analysis.identification.estimators.linear_model import tests_design
from analysis.identification.io.measurements import COMPONENTS, TestArrays

ROBUST_METHODS = ("none", "huber", "tukey")
#: Huber's tuning constant (95 % efficiency under Gaussian noise)
HUBER_C = 1.345
#: Tukey's biweight tuning constant (95 % efficiency under Gaussian noise)
TUKEY_C = 4.685
#: the weights have converged when none changes by more than this between iterations
WEIGHT_TOL = 1e-6
#: iterations of reweighting allowed for each estimator
MAX_ITER = 50
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
            "covariance": "weighted fit with the final weights fixed: G Sigma G^T",
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
    return fit_linear(robot, sub, joints, noise, weighted=True, weights=w, start=start, J=J)


def _model(robot, tests, joints, method, x_p, J, A_lin):
    """(m, 6) prediction and (m, 6, p) model Jacobian at x_p for every measured component."""
    if method == "exact":
        from analysis.identification.estimators.exact_model import model_displacement

        f, F = model_displacement(robot, tests.q, _full(x_p, joints)[None, :], tests.w)
        return f, F[..., list(joints)] * tests.measured[..., None]
    from analysis.identification.streaming.per_test import apply

    return apply(A_lin, x_p), A_lin


def _irls(robot, tests, joints, noise, method, weight_fn, c, x, weights, J, A_lin):
    """Reweight until the weights move by <= WEIGHT_TOL; returns x, weights, r, iterations."""
    for it in range(1, MAX_ITER + 1):
        f = _weighted_fit(robot, tests, joints, noise, method, weights, x, J)
        x = f.x
        pred, _ = _model(robot, tests, joints, method, x, J, A_lin)
        r = np.where(tests.measured, (tests.d - pred) / _sigma(noise, J, x, tests, joints),
                     np.nan)
        new = np.where(tests.measured, weight_fn(np.nan_to_num(r), c), 1.0)
        moved = np.abs(new - weights)
        weights = new
        change = float(np.max(moved))
        if change <= WEIGHT_TOL:
            return x, weights, r, it
    i, j = np.unravel_index(int(np.argmax(moved)), weights.shape)
    raise InputError(
        f"the robust fit did not settle in {MAX_ITER} reweighting iterations (weights still "
        f"change by {change:.2g}, e.g. line {tests.line[i]} {COMPONENTS[j]}); the data hold "
        "competing explanations: inspect the residuals or use --robust huber",
        where="--robust")


def robust_fit(robot, tests: TestArrays, joints: tuple[int, ...], noise, method: str,
               robust: str, start: np.ndarray, J=None) -> RobustFit:
    """Huber or Tukey IRLS around the fit ``method`` ("wls" or "exact") from ``start`` (p,).

    See the module docstring for the weights, the scale and the covariance. ``J``: the
    tests' Jacobians (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`) if
    the caller has them.
    """
    if robust not in ("huber", "tukey"):
        raise InputError(f"unknown robust estimator {robust!r}: expected one of "
                         f"{', '.join(ROBUST_METHODS)}", where="--robust")
    if method not in ("wls", "exact"):
        raise InputError("robust fitting weights the residuals whitened by the noise model: "
                         "use --method exact (or wls), not ols", where="--robust")
    J, A_lin = tests_design(robot, tests, joints, J)
    ones = np.ones(tests.measured.shape)
    x, weights, r, n_it = _irls(robot, tests, joints, noise, method, huber_weight, HUBER_C,
                                np.asarray(start, dtype=float), ones, J, A_lin)
    c = HUBER_C
    if robust == "tukey":
        c = TUKEY_C
        start_w = np.where(tests.measured, tukey_weight(np.nan_to_num(r), c), 1.0)
        x, weights, r, more = _irls(robot, tests, joints, noise, method, tukey_weight, c, x,
                                    start_w, J, A_lin)
        n_it += more
    # the final fit at the converged weights: its G is the weighted estimator
    final = _weighted_fit(robot, tests, joints, noise, method, weights, x, J)
    # G's columns of components with weight 0 are zero: they do not enter x
    pred, A = _model(robot, tests, joints, method, final.x, J, A_lin)
    cov = _covariances(noise, J, _full(final.x, joints), tests.measured, tests.w)
    # G = final.bread A^T W_weighted, kept factored (memory linear in the tests)
    fit = Fit(x=final.x, A=A, cov=cov, predicted=pred, iterations=n_it, bread=final.bread,
              Linv=final.Linv, eiv_shift=final.eiv_shift)
    down = tuple(
        DownWeighted(test=int(i), line=int(tests.line[i]), pose=str(tests.pose[i]),
                     component=COMPONENTS[j], weight=float(weights[i, j]),
                     whitened_residual=float(r[i, j]))
        for i, j in zip(*np.nonzero(tests.measured & (weights < REPORT_BELOW)), strict=True))
    return RobustFit(method=robust, constant=c, fit=fit, weights=weights, whitened=r,
                     iterations=n_it, down_weighted=down)

