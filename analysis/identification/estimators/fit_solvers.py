"""The fits behind the estimators: OLS/WLS of the linear model, the exact fit.

``identify`` (:mod:`analysis.identification.estimate`) chooses among them and
builds the result; leave-one-pose-out validation
(:mod:`analysis.identification.validation.crossval`) refits with them. Both import this
module, which imports neither.
"""

from __future__ import annotations

import numpy as np

from analysis.errors import InputError
from analysis.identification.corrections.wrench_eiv import corrected, wrench_eiv_matrix
from analysis.identification.estimators.fit_record import Fit
from analysis.identification.estimators.gauss_newton import gauss_newton
from analysis.identification.estimators.linear_model import jacobian_blocks, tests_design
from analysis.identification.linalg.lsq import solve_blocks, whitening
from analysis.identification.noise import NoiseModel
from analysis.identification.streaming.covariances import (
    covariance_and_whitening,
    covariances_per_test,
    per_test_covariance,
    whitening_per_test,
)
from analysis.identification.streaming.per_test import (
    apply,
)

#: refuse when the wrench noise attenuates some compliance by more than this fraction
#: (:mod:`analysis.identification.corrections.wrench_eiv`; ~(sigma_w/|w|)^2: loads under ~5x the
#: F/T noise)
EIV_LIMIT = 0.05


def _covariances(noise: NoiseModel, J: np.ndarray, x_full: np.ndarray, measured,
                 w: np.ndarray | None = None, weights: np.ndarray | None = None,
                 out: np.ndarray | None = None) -> np.ndarray:
    return covariances_per_test(noise, J, x_full, measured, w, weights, out)


def _fit_covariances(noise: NoiseModel, J: np.ndarray, x_full: np.ndarray, measured,
                     w: np.ndarray | None = None, weights: np.ndarray | None = None):
    """A fit's ``cov``: :func:`_covariances`, or for one large campaign a
    :class:`~analysis.identification.streaming.covariances.PerTestCovariance` made when used."""
    return per_test_covariance(noise, J, x_full, measured, w, weights)


def _linear_estimator(A, d, measured, cov, weighted: bool, Linv=None):
    """x = G d for per-test blocks; returns x, bread (p, p), Linv (m, 6, 6) or None.

    G = bread A^T Linv^T Linv (bread A^T for OLS), see :class:`Fit`. ``Linv``: the
    whitening of ``cov`` if the caller has it (``cov`` is then not used).
    """
    dz = np.where(measured, d, 0.0)
    if weighted and Linv is None:
        Linv = whitening(cov, measured)
    elif not weighted:
        Linv = None
    x, bread = solve_blocks(A, dz, Linv)
    return x, bread, Linv


def _full(x_p: np.ndarray, joints: tuple[int, ...]) -> np.ndarray:
    x = np.zeros(6)
    x[list(joints)] = x_p
    return x


def _wrench_eiv(noise, J, tests, joints, x, bread, Linv, S=None):
    """(x_c, bread_c, shift): the fit corrected for the wrench's errors in variables.

    :mod:`analysis.identification.corrections.wrench_eiv`: ``(N - S) x_c = N x`` with S from each
    test's
    wrench covariance (:meth:`NoiseModel.wrench_sigma_at`) and the fit's weights (``S``
    if the caller has it).
    """
    if S is None:
        S = wrench_eiv_matrix(J, noise.wrench_sigma_at(tests.w) ** 2, Linv, tests.measured,
                              cols=list(joints))
    # relative attenuation: the eigenvalues of bread S (similar to a symmetric PSD matrix)
    rho = float(np.max(np.abs(np.linalg.eigvals(bread @ S))))
    if not rho <= EIV_LIMIT:
        raise InputError(
            f"the loads are too small against the force/torque sensor noise "
            f"({noise.force_sigma:.3g} N, {noise.moment_sigma:.3g} N m): its errors in the "
            f"regressor attenuate the compliances by up to {100 * rho:.2g} % (limit "
            f"{100 * EIV_LIMIT:g} %), beyond a first-order correction; load the robot well "
            "above the sensor noise, or check the F/T noise figures (the protocol's, the "
            "sidecar's, or --force-sigma-N/--moment-sigma-Nm; these are per test row)",
            where="wrench")
    x_c, bread_c = corrected(x, bread, S)
    return x_c, bread_c, x_c - x


def fit_linear(robot, tests, joints, noise, weighted: bool, weights=None, start=None,
               eiv: bool = True, design=None, first_whitening: dict | None = None,
               J=None) -> Fit:
    """OLS (``weighted=False``) or WLS fit of the linear model (eqs. 16-18).

    WLS only: ``weights`` (m, 6) robust weights (:func:`_covariances`; ``cov`` of the
    result is then the weighted one), ``start`` (p,) compliances to evaluate the first
    weights at instead of the OLS estimate. ``eiv``: correct the bias of the wrench
    noise in the regressor (:mod:`analysis.identification.corrections.wrench_eiv`).
    ``design``: (J, A) of
    :func:`~analysis.identification.estimators.linear_model.tests_design` for these tests
    and joints, if the caller has them; else ``J``, the tests'
    :func:`~analysis.identification.estimators.linear_model.jacobian_blocks`, if the
    caller has it.
    ``first_whitening``: a dict that receives ``x`` and ``Linv``, the compliances and
    the whitening of the first WLS pass (an exact fit started at the same x needs the
    same whitening first).
    """
    J, A = tests_design(robot, tests, joints, J) if design is None else design
    if weighted and start is not None:
        x = np.asarray(start, dtype=float)  # no OLS solve: the weights start at ``start``
    else:
        x, bread, Linv = _linear_estimator(A, tests.d, tests.measured, None, weighted=False)
    if weighted:
        for n in range(2):
            if n == 0:  # only the last pass's covariances are kept: whitened block by block
                cov, Lw = None, whitening_per_test(noise, J, _full(x, joints), tests.measured,
                                                   tests.w, weights)
            else:  # kept by the fit: made again block by block where used
                cov, Lw = covariance_and_whitening(noise, J, _full(x, joints), tests.measured,
                                                   tests.w, weights)
            x0 = x
            x, bread, Linv = _linear_estimator(A, tests.d, tests.measured, cov, weighted=True,
                                               Linv=Lw)
            del Lw
            if n == 0 and first_whitening is not None:
                first_whitening.update(x=np.array(x0, dtype=float), Linv=Linv)
    shift = None
    if eiv:
        x, bread, shift = _wrench_eiv(noise, J, tests, joints, x, bread, Linv)
    if not weighted:  # at the final estimate (WLS: the weights it was fitted with)
        cov = _fit_covariances(noise, J, _full(x, joints), tests.measured, tests.w)
    pred = apply(A, x)
    return Fit(x=x, A=A, cov=cov, predicted=pred, iterations=0, bread=bread, Linv=Linv,
               eiv_shift=shift)


def fit_exact(robot, tests, joints, noise, start: np.ndarray, weights=None,
              eiv: bool = True, first_whitening: dict | None = None, sums=None,
              J=None) -> Fit:
    """Weighted Gauss-Newton on the exact equilibrium model, from compliances ``start`` (p,).

    ``weights`` (m, 6): robust weights (:func:`_covariances`); ``cov`` of the result is
    then the weighted one. ``eiv``: solve the estimating equation corrected for the
    wrench noise in the regressor, ``F^T W (d - f(x)) + S x = 0``, by one Newton step
    from the Gauss-Newton minimum (:mod:`analysis.identification.corrections.wrench_eiv`).
    ``first_whitening``: {x, Linv} of :func:`fit_linear`'s first WLS pass; used as the
    first iteration's whitening when its x equals ``start`` (the same array
    Gauss-Newton would compute: computed once).

    ``sums``: a :class:`~analysis.identification.streaming.fold_sums.FinalPassSums` to fill
    in the pass that forms the final system, where the systems make one
    (:meth:`~analysis.identification.streaming.systems.LinearisedSystems.final_pass_sums`;
    the others refuse it): the errors-in-variables S comes from it, and ``predicted`` is
    left None, for the statistics pass to make from ``A`` (the model Jacobian, whose blocks
    come with the model's values) and move by A eiv_shift (``predicted_shifted`` False).
    ``J``: the tests'
    :func:`~analysis.identification.estimators.linear_model.jacobian_blocks` if the caller has it.
    """
    Linv0 = None
    if (first_whitening and weights is None
            and np.array_equal(first_whitening["x"], np.asarray(start, dtype=float))):
        Linv0 = first_whitening["Linv"]
    J = jacobian_blocks(robot, tests.q) if J is None else J
    gn = gauss_newton(robot, tests.q, tests.w, tests.d, tests.measured, joints, noise, start,
                      weights=weights, J=J, Linv0=Linv0, rows=sums, values=sums is None,
                      w_ref=tests.w_ref)
    if not gn.valid:
        raise InputError(
            "the exact fit cannot start: the equilibrium has no solution at the linear "
            "estimate of the compliances (some k far too small, or negative); check the "
            "data or use --method wls", where="--method")
    # the linearised estimator at the solution: bread = (F^T W F)^-1 = gn.cov_x
    x, bread, f, Linv, shift = gn.x, gn.cov_x, gn.f, gn.Linv, None
    shifted = True
    if eiv:
        S = sums.S if sums is not None else None
        x, bread, shift = _wrench_eiv(noise, J, tests, joints, x, bread, Linv, S)
        if sums is not None:
            shifted = False
        else:
            f = f + apply(gn.F, shift)  # first order: the shift is ~1e-4 of x
    return Fit(x=x, A=gn.F, cov=gn.cov, predicted=f, iterations=gn.iterations,
               bread=bread, Linv=Linv, eiv_shift=shift, deflection=gn.dq, R=gn.R,
               predicted_shifted=shifted)



def fit(robot, tests, joints, noise, method, J=None) -> Fit:
    """Fit by ``method`` (ols, wls, exact); ``J``: the tests'
    :func:`~analysis.identification.estimators.linear_model.jacobian_blocks`."""
    if method == "ols":
        return fit_linear(robot, tests, joints, noise, weighted=False, J=J)
    if method == "wls":
        return fit_linear(robot, tests, joints, noise, weighted=True, J=J)
    start = fit_linear(robot, tests, joints, noise, weighted=False, J=J).x
    return fit_exact(robot, tests, joints, noise, start, J=J)
