"""Identification of joint compliances x = 1/k from stiffness tests.

Estimators (``method``):

``ols``
    The paper's estimator (eqs. 16-21): unweighted least squares on the
    stacked A (6m x p) of the linear model, solved by QR of the
    column-scaled A (no normal equations). Its covariance is the sandwich
    A^+ Sigma A^+T with Sigma from the noise model.
``wls``
    Linear model, weighted by the inverse measurement covariance of each test
    (:func:`analysis.identification.noise.residual_covariance`: translation sigma (m) and
    rotation sigma (rad) on the diagonal, plus the wrench noise propagated
    through the Cartesian compliance at the current estimate; two
    reweighting passes from the OLS estimate). Whitening uses each test's
    Cholesky factor; best linear unbiased estimator under the noise model.
``exact`` (default)
    Weighted Gauss-Newton on the nonlinear equilibrium model
    (:mod:`analysis.identification.exact_fit`), started from OLS, with step halving. The
    measured displacement is finite, so the linear model is biased by the
    linearisation error (about 1-2 % of the deflection of the KR240-2 under
    the paper's w_eff, the size of the tracker noise); the exact fit removes
    it for a few ms of computation, and it is the maximum-likelihood
    estimate under the Gaussian noise model.

Covariance (``covariance``): ``"model"`` (default) takes the noise model's
sigmas as known, since a campaign of 5 tests has too few residual degrees of
freedom for a reliable variance estimate, and the instruments are
calibrated; the reduced chi-square and its p-value are reported as the check
of that assumption. ``"residual"`` scales the covariance by the reduced
chi-square and uses Student t intervals. Intervals: see
:mod:`analysis.identification.uncertainty`.

Joints not in ``joints`` are taken as rigid (x = 0). Without any rotation
measurement the default is joints 1-3 with the wrist rigid (Knapczyk-Ryska,
Alici-Shirinzadeh).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification import per_test
from analysis.identification.fitting import (  # noqa: F401 (re-exported: the public entry points stay)
    COND_LIMIT,
    _covariances,
    _design,
    _fit_covariances,
    _full,
    _jacobian,
    _linear_estimator,
    check_identifiable,
    check_tests,
    fit,
    fit_exact,
    fit_linear,
)
from analysis.identification.lsq import (
    TEST_BLOCK,
    TallR,
    per_test_diagonal,
    sandwich_and_residual_variance,
    scaled_condition,
    stack_matrix,
    whitening,
)
from analysis.identification.measurements import TestArrays, to_arrays
from analysis.identification.noise import NoiseModel
from analysis.identification.per_test import PerTestSigma, apply
from analysis.identification.poses import pose_tolerance
from analysis.identification.result import (
    RESIDUALS_LISTED,
    Fit,
    IdentificationResult,
    ResidualRows,
)
from analysis.identification.robust import ROBUST_METHODS, robust_fit
from analysis.identification.uncertainty import (
    chi2_summary,
    critical_value,
    stiffness_interval,
)
from analysis.model.robot_model import RobotModel
from analysis.report.formatting import level

METHODS = ("ols", "wls", "exact")
DEFAULT_METHOD = "exact"
#: family-wise level of the outlier test: the chance that any residual of a fit to data
#: that follow the noise model is flagged
OUTLIER_FAMILY_LEVEL = 0.01


def outlier_threshold(n_residuals: int, level: float = OUTLIER_FAMILY_LEVEL) -> float:
    """|studentized residual| beyond which a residual is an outlier (Sidak correction).

    Each of the n residuals is tested two-sided at 1 - (1 - level)^(1/n), so
    that with data that follow the noise model the chance of flagging any of
    them is ``level``; a fixed 3-sigma cut flags ~0.27 % of innocent
    residuals, i.e. a few in every campaign of a few hundred components.
    """
    from scipy import special  # norm.isf(p) = -ndtri(p), without importing scipy.stats

    n = max(int(n_residuals), 1)
    per_residual = -np.expm1(np.log1p(-level) / n)  # 1 - (1 - level)^(1/n), accurately
    return float(-special.ndtri(per_residual / 2.0))


def _blocks(m: int, block: int | None = None):
    """Slices of ``block`` (default :data:`TEST_BLOCK`) consecutive tests covering 0..m."""
    block = TEST_BLOCK if block is None else block
    return [slice(s, s + block) for s in range(0, m, block)]


def parse_joints(text: str | Sequence[int] | None, n: int = 6) -> tuple[int, ...] | None:
    """``"1,2,3"`` (1-based) -> (0, 1, 2); None stays None."""
    if text is None:
        return None
    items = text.split(",") if isinstance(text, str) else list(text)
    out = []
    for item in items:
        try:
            j = int(str(item).strip())
        except ValueError as err:
            raise InputError(f"{item!r} is not a joint number 1..{n}", where="--joints") from err
        if not 1 <= j <= n:
            raise InputError(f"joint {j} is out of range 1..{n}", where="--joints")
        out.append(j - 1)
    if len(set(out)) != len(out) or not out:
        raise InputError("list each joint once, e.g. 1,2,3", where="--joints")
    return tuple(sorted(out))


#: the errors-in-variables correction is a warning when it moves some k by this many se
EIV_WARN_SE = 0.1

#: at most this many residuals are set aside one by one by :func:`flag_outliers`
MAX_OUTLIERS = 10
#: campaigns of more measured components than this set aside every residual beyond the
#: threshold at once in each round of :func:`flag_outliers`
OUTLIERS_AT_ONCE_ABOVE = 100_000
#: ... when the leverages of the residuals set aside together sum to at most this (else
#: the largest alone): setting them aside then moves any other residual's t by at most
#: about sqrt(this * h_j) |t|, far below the threshold's resolution
AT_ONCE_MAX_LEVERAGE = 1e-3


def _studentized_matrix(tests: TestArrays, f: Fit, scale: float) -> np.ndarray:
    """(m, 6) studentized residuals of fit ``f`` (NaN where not measured)."""
    _, var_r = sandwich_and_residual_variance(f.A, f.cov, f.bread, f.Linv)
    return _studentize(tests, f.predicted, var_r, scale)


def _studentize(tests: TestArrays, predicted: np.ndarray, var_r: np.ndarray,
                scale: float) -> np.ndarray:
    """(m, 6) residuals / sqrt(scale var_r), NaN where not measured or var_r is 0, written
    into ``var_r``'s array block by block ((m, 6) arrays are 48 MB each at 1e6 tests)."""
    for sl in _blocks(tests.m, 1 << 16):
        v = var_r[sl]
        with np.errstate(divide="ignore", invalid="ignore"):
            bad = ~(v > 0) | ~tests.measured[sl]
            v[...] = (tests.d[sl] - predicted[sl]) / np.sqrt(v * scale)
        v[bad] = np.nan
    return var_r


def _beyond(t: np.ndarray, mask: np.ndarray, threshold: float) -> np.ndarray:
    """Flat indices of the components with ``mask`` and |t| > threshold, block by block."""
    flat_t, flat_m = t.reshape(-1), mask.reshape(-1)
    step = 1 << 18
    return np.concatenate([s + np.flatnonzero(flat_m[s:s + step]
                                              & (np.abs(flat_t[s:s + step]) > threshold))
                           for s in range(0, flat_t.size, step)] or [np.zeros(0, int)])


def flag_outliers(robot, tests: TestArrays, joints, noise, method: str, first: Fit,
                  scale: float, threshold: float, t_first: np.ndarray | None = None,
                  bias_se: np.ndarray | None = None) -> np.ndarray:
    """(m, 6) bool: residuals beyond ``threshold``, found one at a time.

    A gross error pulls the fit towards itself and inflates the residuals of
    its neighbours (the other components of its test, tests at the same
    pose), so only the largest |t| is tested; if beyond ``threshold`` it is set
    aside, the rest is refitted and tested again (a sequential, Grubbs-like
    procedure), at most :data:`MAX_OUTLIERS` times or while equations remain.
    ``t_first``: the (m, 6) studentized residuals of ``first`` if the caller has them.
    ``bias_se`` (p,): for a linear fit whose linearisation bias was corrected, the
    standard errors of ``first``; each refit is then corrected too and its residuals
    are those of the exact model at the corrected estimate, as for ``first``.

    Above :data:`OUTLIERS_AT_ONCE_ABOVE` measured components, each round sets aside
    every residual beyond the threshold (largest |t| first, within the same budget)
    and refits once, when their leverages sum to at most :data:`AT_ONCE_MAX_LEVERAGE`
    (else the largest alone): a residual's leverage is then of order p / n, so setting
    one aside barely moves the others' t, and a round per residual would cost a pass
    over every test each. The rounds go on until the rest of the residuals are within
    the threshold, as one at a time.
    """
    flags = np.zeros(tests.measured.shape, dtype=bool)
    current = first
    t = _studentized_matrix(tests, first, scale) if t_first is None else t_first
    n_eq = int(tests.measured.sum())
    budget = min(MAX_OUTLIERS, n_eq - len(joints) - 1)
    at_once = n_eq > OUTLIERS_AT_ONCE_ABOVE
    for _ in range(max(budget, 0) + 1):
        room = budget + 1 - int(flags.sum())
        if at_once:
            beyond = _beyond(t, tests.measured & ~flags, threshold)
            size = np.abs(t.reshape(-1)[beyond])
            order = beyond[np.argsort(-size, kind="stable")][:room]
            i, c = np.unravel_index(order, t.shape)
            if not len(order):
                break
            if np.sum(_leverages(current, i, c)) > AT_ONCE_MAX_LEVERAGE:
                i, c = i[:1], c[:1]  # influential: one at a time
        else:
            candidate = np.where(tests.measured & ~flags & np.isfinite(t), np.abs(t), -np.inf)
            i, c = np.unravel_index(int(np.argmax(candidate)), candidate.shape)
            if not candidate[i, c] > threshold:
                break
        flags[i, c] = True
        if int(flags.sum()) > budget:
            break
        keep = tests.measured & ~flags
        # d as it is: components not ``measured`` are not read (no 48 MB copy at 1e6 tests)
        rest = TestArrays(tests.pose, tests.q, tests.w, tests.d, keep, tests.line)
        try:
            current = _refit_without(robot, rest, joints, noise, method, current, i, c,
                                     tests.d[i, c])
            if bias_se is not None:
                from analysis.identification.linear_bias import correct_linear_bias

                correct_linear_bias(robot, rest, joints, current, bias_se, method,
                                    in_place=True)
            t = None  # its 48 MB (1e6 tests) before the next
            t = _studentized_matrix(rest, current, scale)
        except InputError:
            break
    return flags


def _leverages(f: Fit, i: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Leverage ``a^T bread a`` of the (whitened) rows (i, c) of fit ``f``'s system."""
    out = np.empty(len(i))
    for k, (ti, ci) in enumerate(zip(i.tolist(), c.tolist(), strict=True)):
        a = np.asarray(f.A[ti], dtype=float)  # (6, p) the test's rows
        a = (np.asarray(f.Linv[ti]) @ a)[ci] if f.Linv is not None else a[ci]
        out[k] = float(a @ f.bread @ a)
    return out


#: a downdated OLS refit falls back to a full refit when the removed row's leverage
#: exceeds this (1 - h small: the rank-1 downdate would lose digits)
DOWNDATE_MAX_LEVERAGE = 0.5


def _refit_without(robot, rest: TestArrays, joints, noise, method: str, prev: Fit,
                   i, c, d_ic) -> Fit:
    """The fit of ``method`` to ``rest``: ``prev``'s data without component(s) (i, c).

    ``i``, ``c``: a test and a component, or equal-length arrays of them; ``d_ic``: the
    removed measurement(s). A downdated OLS fit shares ``prev.A`` (rows of the
    removed components included, see below; ``predicted`` there is A x of those rows):
    its estimate, bread, covariance and the studentized residuals of ``rest`` are those
    of the refit; its covariances are made block by block where used in a large
    campaign (:func:`_fit_covariances`).

    OLS: rank-1 downdates of prev's (A^T A)^-1 (Sherman-Morrison), one per removed
    row, instead of a new QR of the whole design: ``bread' = bread + g g^T / (1 - h)``,
    ``g = bread a``, ``h = a^T g`` the leverage of the removed row a,
    ``x' = x - bread' a (d - a^T x)``; the same least-squares solution, at O(p^2)
    instead of a pass over 6m rows (full refit when some h > :data:`DOWNDATE_MAX_LEVERAGE`).
    Exact: Gauss-Newton warm-started at prev's estimate (same minimum, fewer iterations
    than from OLS). WLS: full refit.
    """
    rows = list(zip(np.atleast_1d(i).tolist(), np.atleast_1d(c).tolist(),
                    np.atleast_1d(d_ic).astype(float).tolist(), strict=True))
    if method == "ols" and prev.Linv is None:
        x, bread, shift = prev.x, prev.bread, prev.eiv_shift
        J = _jacobian(robot, rest.q)
        for ti, ci, di in rows:
            a = np.array(prev.A[ti, ci], dtype=float)
            g = bread @ a
            h = float(a @ g)
            if not 0.0 <= h <= DOWNDATE_MAX_LEVERAGE:
                break
            bread = bread + np.outer(g, g) / (1.0 - h)
            x = x - (bread @ a) * (di - a @ x)
            if shift is not None:
                # the removed row's part of S leaves too: (N - S + dS)^-1, as a p x p update
                from analysis.identification.eiv import corrected, wrench_eiv_matrix

                row = np.zeros((1, 6), dtype=bool)
                row[0, ci] = True
                dS = wrench_eiv_matrix(J[ti:ti + 1][..., list(joints)],
                                       noise.wrench_sigma_at(rest.w[ti:ti + 1]) ** 2,
                                       measured=row)
                x_new, bread = corrected(x, bread, -dS)
                # approximate (the rest's uncorrected x is not formed): these fits only
                # serve the outlier test, which does not report the shift
                shift = shift + x_new - x
                x = x_new
        else:
            cov = _fit_covariances(noise, J, _full(x, joints), rest.measured, rest.w)
            # A keeps the removed rows (no 0.3 GB copy at 1e6 tests): cov has zero rows and
            # columns there, so they add nothing to the sandwich or the residual variances,
            # and their residuals are NaN in ``rest``; x and bread are the downdated ones
            return Fit(x=x, A=prev.A, cov=cov, predicted=apply(prev.A, x),
                       iterations=0, bread=bread, Linv=None, eiv_shift=shift)
    if method == "exact":
        return fit_exact(robot, rest, joints, noise, start=prev.x)
    return fit(robot, rest, joints, noise, method)


def _validation_flags(validation: pd.DataFrame, named: int = 5) -> list[str]:
    """A warning naming the held-out poses beyond the limit of the total-uncertainty check
    (:mod:`analysis.identification.holdout_check`), or nothing."""
    beyond = validation[validation["beyond_limit"].to_numpy(dtype=bool)]
    if not len(beyond):
        return []
    from analysis.identification.holdout_check import HOLDOUT_FAMILY_LEVEL

    worst = beyond.sort_values("rms_normalized_total", ascending=False).head(named)
    text = ", ".join(f"pose {r.held_out_pose} at {r.rms_normalized_total:.2f} (limit "
                     f"{r.limit_normalized_total:.2f}, p = {r.p_value_total:.2g})"
                     for r in worst.itertuples())
    more = f" and {len(beyond) - named} more" if len(beyond) > named else ""
    return [f"{len(beyond)} held-out pose(s) predicted worse than their total uncertainty "
            f"(noise and the refit's parameter uncertainty; Sidak, "
            f"{level(HOLDOUT_FAMILY_LEVEL)} family-wise over {len(validation)} poses): "
            f"{text}{more}; the model or the data of these poses is suspect"]


#: residual tables of more rows than this are held in memory only for the tests with the
#: largest |studentized| residuals (:class:`ResidualRows`; results.json lists 1000 rows and
#: the report 200 tests); the whole table is written to residuals.csv block by block
RESIDUAL_ROWS_HELD = 100_000


def identify(
    robot: RobotModel,
    tests: TestArrays,
    method: str = DEFAULT_METHOD,
    joints: Sequence[int] | None = None,
    noise: NoiseModel | None = None,
    covariance: str = "model",
    cond_limit: float = COND_LIMIT,
    outlier_level: float = OUTLIER_FAMILY_LEVEL,
    validate: bool = True,
    confidence: float = 0.95,
    robust: str = "none",
    holdout_radius: float | None = None,
) -> IdentificationResult:
    """Identify joint stiffness from tests; see the module docstring for the estimators.

    Parameters
    ----------
    robot : the robot model (6 joints).
    tests : :class:`analysis.identification.measurements.TestArrays` (SI).
    method : "ols", "wls" or "exact".
    joints : 0-based joints to identify (others rigid); default all six, or
        (0, 1, 2) when no rotation is measured.
    noise : instrument noise model (default :class:`NoiseModel()`).
    covariance : "model" (known sigmas) or "residual" (scaled by reduced chi-square).
    outlier_level : family-wise level of the outlier test (:func:`outlier_threshold`).
    validate : run leave-one-pose-out validation (needs >= 3 poses).
    robust : "none" (the Gaussian fit), "huber" or "tukey": IRLS around ``method``
        (:mod:`analysis.identification.robust`). The chi-square, the noise-ratio notes
        and the validation then use the components kept (weight >= 0.5); the
        ``outlier`` column marks the ones down-weighted below it.
    holdout_radius : poses closer than this (rad, ||dq|| over the joints) are held out
        together in the validation; default
        :data:`analysis.identification.holdout_check.CLUSTER_DEG` (the planner's default
        minimum separation; a run passes its protocol's).
    """
    from threadpoolctl import threadpool_limits

    # the work is batched 6 x 6 and tall-skinny (6000 x 7) linear algebra: a second BLAS
    # thread does not speed it up, and on a shared machine its spin-waiting costs CPU
    # (measured: TSQR of 6e5 x 7 rows 0.02-0.06 s in one thread, 0.13-0.36 s in two)
    with threadpool_limits(limits=1):
        return _identify(robot, tests, method, joints, noise, covariance, cond_limit,
                         outlier_level, validate, confidence, robust, holdout_radius)


def _identify(robot, tests, method, joints, noise, covariance, cond_limit, outlier_level,
              validate, confidence, robust, holdout_radius) -> IdentificationResult:
    """:func:`identify` in the calling thread's BLAS thread limit."""
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}: expected one of {', '.join(METHODS)}",
                         where="--method")
    if covariance not in ("model", "residual"):
        raise InputError(f"expected 'model' or 'residual', got {covariance!r}",
                         where="covariance")
    if robust not in ROBUST_METHODS:
        raise InputError(f"unknown robust estimator {robust!r}: expected one of "
                         f"{', '.join(ROBUST_METHODS)}", where="--robust")
    noise = noise or NoiseModel()
    if joints is None:
        joints = tuple(range(6)) if tests.has_rotations else (0, 1, 2)
    joints = tuple(sorted({int(j) for j in joints}))
    if not joints or joints[0] < 0 or joints[-1] > 5:
        raise InputError(f"expected 0-based joint indices 0..5, got {joints}", where="joints")
    from analysis.identification.poses import pose_groups

    group = pose_groups(tests.q, pose_tolerance(noise))  # once: 1-2 s at 1e6 tests
    check_tests(robot, tests, joints, noise, group=group)
    from analysis.identification.holdout_check import CLUSTER_DEG, holdout_folds

    if holdout_radius is None:
        holdout_radius = np.radians(CLUSTER_DEG)
    # the validation's folds: the poses, nearby ones together
    fold = holdout_folds(tests.q, group, holdout_radius) if validate else group
    design = _design(robot, tests, joints)
    cond = check_identifiable(design[1], joints, cond_limit)
    warnings: list[str] = []
    if not tests.has_rotations and any(j >= 3 for j in joints):
        warnings.append("no rotation measured: wrist joints are identified from translations "
                        "only, expect wide intervals")
    if not tests.has_rotations and joints == (0, 1, 2):
        warnings.append("translational-only variant: wrist joints 4-6 taken as rigid; their "
                        "compliance, if any, is absorbed by k1..k3")

    # only the estimates of the linear fits are kept, and each fit is dropped before the
    # next is made: their per-test arrays are ~1 kB per test
    chosen = fit_linear(robot, tests, joints, noise, weighted=False, design=design)
    linear_x = {"ols": chosen.x}
    first: dict = {}
    # a streamed exact fit starts from OLS and makes its own weights: WLS would be two
    # passes over every test for a comparison only (results.json lists ols alone then)
    if method == "wls" or (method == "exact" and tests.m <= per_test.LAZY_TESTS):
        # WLS has the same design; its weights start at the uncorrected OLS estimate (it
        # solves that itself: the OLS fit's x is the errors-in-variables corrected one). The
        # OLS fit's covariances are let go first (0.3 GB at 1e6 tests)
        chosen = None
        chosen = fit_linear(robot, tests, joints, noise, weighted=True, design=design,
                            first_whitening=first if method == "exact" else None)
        linear_x["wls"] = chosen.x
    del design
    sums = None
    if method == "exact":
        chosen = None
        if tests.m > per_test.LAZY_TESTS and robust == "none":
            # streamed: the errors-in-variables S and the validation's per-pose sums are
            # made in the pass that forms the final system (no passes of their own)
            from analysis.identification.crossval import FinalPassSums

            folds = int(fold.max(initial=-1)) + 1
            sums = FinalPassSums(tests, joints, noise, fold if validate and folds >= 3
                                 else None, folds)
        # the first Gauss-Newton weights are WLS's first ones (both at the OLS estimate)
        chosen = fit_exact(robot, tests, joints, noise, start=linear_x["ols"],
                           first_whitening=first or None, sums=sums,
                           defer_shift=sums is not None)
    del first
    rob = None
    kept = tests.measured
    if robust != "none":
        rob = robust_fit(robot, tests, joints, noise, method, robust, start=chosen.x)
        chosen = rob.fit
        kept = rob.kept(tests.measured)

    if tests.m > per_test.LAZY_TESTS:
        per_test.release_freed_heap()  # the fit's freed pages, before the validation
    corr = None
    if method in ("ols", "wls"):
        # the linear model's bias corrected (before the validation, which corrects its folds
        # too); where reliable, the residuals (chi-square, outliers, notes) are those of the
        # exact model at the corrected estimate
        from analysis.identification.linear_bias import correct_linear_bias
        from analysis.identification.lsq import sandwich

        # chosen.predicted becomes f(x_c) in place where the correction is reliable
        corr = correct_linear_bias(robot, tests, joints, chosen, np.sqrt(np.diag(
            sandwich(chosen.A, chosen.cov, chosen.bread, chosen.Linv))), method,
            in_place=True)
    if rob is not None:  # the M-estimator's sandwich, on residuals free of the linear misfit
        rob = rob.with_covariance(None if corr is None or not corr.reliable else
                                  corr.predicted - apply(chosen.A, corr.x))
    # validation first: a streamed exact fit's per-pose sums (and its deflections, Newton's
    # start for the held-out tests) are let go before the per-test statistics are made
    validation = None
    if validate:
        from analysis.identification.crossval import leave_one_pose_out

        # robust: validated on the components the robust fit kept (weight >= 0.5)
        valid_tests = tests if rob is None else TestArrays(
            tests.pose, tests.q, tests.w, np.where(kept, tests.d, np.nan), kept, tests.line)
        validation = leave_one_pose_out(robot, valid_tests, method, joints, noise,
                                        full_fit=chosen if rob is None else None,
                                        group=fold, cluster_rad=holdout_radius,
                                        fold_sums=sums,
                                        linear_shift=None if corr is None or not corr.reliable
                                        else (corr.x - corr.x_raw, corr.propagation))
    if validation is not None:
        warnings += _validation_flags(validation)
    sums = None
    if chosen.R is not None:
        chosen.deflection = None  # 48 MB at 1e6 tests, not used beyond the validation
    if tests.m > per_test.LAZY_TESTS:
        per_test.release_freed_heap()  # the blocks' freed pages, before the statistics

    p = len(joints)
    n_eq = int(tests.measured.sum())
    # the goodness of fit is that of the components the fit rests on
    dof = int(kept.sum()) - p
    streamed = chosen.R is not None and rob is None
    if streamed:
        # one pass over the recomputed blocks: the variances (meat A^T W A = R^T R, and
        # Sigma W A = A, of a fit whitened by its own covariances), each component's
        # sigma, and the prediction moved by the errors-in-variables shift
        Rp, c0 = chosen.R[:p, :p], chosen.R[:p, p]
        predicted = chosen.predicted
        fill = predicted is None  # the model's values come with A's blocks
        if fill:
            predicted = np.empty(tests.measured.shape)
        move = None if chosen.predicted_shifted else chosen.eiv_shift

        def visit(sl, Ab):
            if fill:
                predicted[sl] = chosen.A.values(sl)
            if move is not None:
                predicted[sl] += Ab @ move

        cov_x, var_r = sandwich_and_residual_variance(
            chosen.A, chosen.cov, chosen.bread, chosen.Linv, meat=Rp.T @ Rp,
            own_weights=True, visit=visit)
        chosen.predicted, chosen.predicted_shifted = predicted, True
        chosen.A.dq = None  # later rows (outliers' leverages) start cold: 48 MB let go
        # chi-square from R: |Linv (r - F shift)|^2 = |c0 - Rp shift|^2 + R[p, p]^2
        shift = np.zeros(p) if chosen.eiv_shift is None else chosen.eiv_shift
        chi2_red, p_value = chi2_summary(float(np.sum((c0 - Rp @ shift) ** 2)
                                               + chosen.R[p, p] ** 2), dof)
        Aw = Rp  # the whitened system's R (same singular values)
    else:
        cov_x, var_r = sandwich_and_residual_variance(chosen.A, chosen.cov, chosen.bread,
                                                      chosen.Linv)
        if rob is not None:  # the M-estimator's sandwich (robust_covariance)
            cov_x = rob.covariance.cov
        # the fit's own whitening when it used the same components, else made block by
        # block (an (m, 6, 6) array is 0.3 GB at 1e6 tests); the same pass gives the R of
        # the whitened system, for its scaled condition without the (6m, p) Linv A
        own = chosen.Linv if rob is None and chosen.Linv is not None else None
        acc = TallR() if tests.m > TEST_BLOCK else None
        chi2 = 0.0  # summed block by block: no (m, 6) residual arrays
        for sl in _blocks(tests.m):
            Lb = own[sl] if own is not None else whitening(chosen.cov[sl], kept[sl])
            rb = np.where(kept[sl], tests.d[sl] - chosen.predicted[sl], 0.0)
            chi2 += float(np.sum(np.einsum("mij,mj->mi", Lb, rb) ** 2))
            if acc is not None:
                acc.add((Lb @ chosen.A[sl]).reshape(-1, p))
        chi2_red, p_value = chi2_summary(chi2, dof)
        Aw = acc.r() if acc is not None else stack_matrix(
            (own if own is not None else whitening(chosen.cov, kept)) @ chosen.A)
    from analysis.identification.noise_check import noise_ratio_notes

    # (m, 6) each component's sigma; for a large campaign made where used (48 MB at 1e6)
    sigma = PerTestSigma(chosen.cov) if per_test.is_lazy(chosen.cov) else np.sqrt(
        per_test_diagonal(chosen.cov))
    warnings += noise_ratio_notes((tests.d, chosen.predicted), sigma, kept, noise,
                                  len(joints))
    scale = 1.0
    crit = critical_value(confidence)
    if covariance == "residual":
        if dof <= 0:
            raise InputError("no residual degrees of freedom to estimate the variance",
                             where="covariance")
        scale = chi2_red
        crit = critical_value(confidence, dof)
    if rob is not None:
        # the sandwich is estimated from the tests' scores already (not scaled by the
        # chi-square); its G scores give it G - p degrees of freedom (robust_covariance)
        crit = critical_value(confidence, rob.covariance.dof)
    cov_x = cov_x * (scale if rob is None else 1.0)
    se_x = np.sqrt(np.diag(cov_x))
    x_out = chosen.x  # the raw linear estimate for ols/wls (the outlier refits start there)
    bias = None
    # systematic terms added to the interval's half-width of x (rad/(N m))
    widen = np.zeros(len(joints))
    if method in ("ols", "wls"):
        from analysis.identification.linear_bias import summary

        se_raw = se_x
        if corr.reliable:
            x_out = corr.x
            cov_x = corr.propagation @ cov_x @ corr.propagation.T
            se_x = np.sqrt(np.diag(cov_x))
        else:  # the raw estimate, its interval widened by |b| where b is known
            widen += np.where(np.isfinite(corr.bias), np.abs(corr.bias), 0.0)
        bias = summary(corr, se_raw, se_x)
        warnings.append(bias["note"])
    from analysis.identification import encoder_eiv

    b_q = encoder_eiv.encoder_bias(robot, tests, joints, x_out, noise)
    widen += np.abs(b_q)
    encoder = encoder_eiv.summary(joints, x_out, b_q, se_x, noise,
                                  min(tests.m, encoder_eiv.MAX_TESTS))
    if max(encoder["bias_in_standard_errors"][j] for j in joints) >= EIV_WARN_SE:
        warnings.append(encoder["note"])
    ci = stiffness_interval(x_out, se_x + widen / crit, crit)
    eiv = None
    if chosen.eiv_shift is not None:
        from analysis.identification.eiv import shift_summary

        eiv = shift_summary(joints, chosen.x, chosen.eiv_shift, se_x, noise)
        # always in results.json and the printed assumptions; a warning only where it
        # moves k by a tenth of its standard error or more (large campaigns)
        if (eiv["max_abs_shift_in_se"] or 0.0) >= EIV_WARN_SE:
            warnings.append(eiv["note"])
    if np.isfinite(p_value) and p_value < 1e-3:
        warnings.append(f"reduced chi-square {chi2_red:.3g} (p = {p_value:.2g}): residuals do "
                        "not match the noise model; check the noise figures or use "
                        "covariance='residual'")
    for idx, j in enumerate(joints):
        if x_out[idx] - crit * se_x[idx] <= 0:
            warnings.append(f"joint {j + 1}: the {level(confidence)} interval of its compliance "
                            "reaches 0, the data do not bound k from above")

    threshold = outlier_threshold(n_eq, outlier_level)
    t = _studentize(tests, chosen.predicted, var_r, scale)  # in var_r's array
    var_r = None
    if rob is None:
        flags = flag_outliers(robot, tests, joints, noise, method, chosen, scale, threshold, t,
                              bias_se=se_raw if bias is not None and bias["reliable"] else None)
    else:
        flags = tests.measured & ~kept
    if tests.m > per_test.LAZY_TESTS:
        per_test.release_freed_heap()  # the passes' freed pages, before the residual table
    rows = ResidualRows(tests, chosen.predicted, sigma, t, flags,
                        None if rob is None else rob.weights, threshold=threshold)
    if n_eq > RESIDUAL_ROWS_HELD:
        residuals = rows.frame(rows.worst_tests(RESIDUALS_LISTED))
    else:
        residuals, rows = rows.frame(), None
    if rob is not None:
        warnings.append(rob.summary())
    flagged = residuals[residuals["outlier"]]
    n_flagged = rows.n_beyond() if rows is not None else len(flagged)
    n_set_aside = int((flags & tests.measured).sum())
    if n_flagged and rob is None:
        where = ", ".join(
            f"test {r.test + 1} line {r.line} (pose {r.pose}) {r.component} "
            f"t = {r.studentized:.1f}"
            for r in flagged.reindex(flagged["studentized"].abs().sort_values(
                ascending=False).index).head(5).itertuples())
        more = f" and {n_flagged - 5} more" if n_flagged > 5 else ""
        rounds = ""
        if n_set_aside != n_flagged:
            aside = residuals[residuals["set_aside"]]
            named = ", ".join(f"line {r.line} (pose {r.pose}) {r.component}"
                              for r in aside.reindex(aside["studentized"].abs().sort_values(
                                  ascending=False).index).head(5).itertuples())
            rounds = (f"; the sequential test (largest |t| first, refit after each) set aside "
                      f"{n_set_aside}" + (f": {named}" if named else "")
                      + (" and more" if n_set_aside > 5 else "")
                      + " (column set_aside); the rest are beyond the threshold in the fit "
                      "to all the data, whose k is reported")
        warnings.append(
            f"{n_flagged} outlier residual(s), |studentized| > {threshold:.2f} (Sidak, "
            f"{level(outlier_level)} family-wise over {n_eq} residuals): {where}{more}{rounds}")
    result = IdentificationResult.build(
        robot=robot.name, method=method, joints=joints, x=x_out, cov_x=cov_x, ci=ci,
        confidence=confidence, covariance=covariance, condition_number=cond,
        condition_number_weighted=float(scaled_condition(Aw)), tests=tests, n_equations=n_eq,
        dof=dof, chi2_reduced=chi2_red, p_value=p_value, residuals=residuals,
        n_poses=int(group.max(initial=-1)) + 1, outlier_threshold=threshold,
        linear=linear_x, iterations=chosen.iterations,
        noise=noise, warnings=warnings,
    )
    result.residual_rows = rows
    result.wrench_eiv = eiv
    result.linear_bias = bias
    result.encoder_eiv = encoder
    if rob is not None:
        result.robust = rob.describe()
    result.validation = validation
    from analysis.identification.fitting import _J_CACHE

    _J_CACHE.clear()  # J is not needed after the identification (0.3 GB at 1e6 tests)
    return result


def analyze_table(
    table: pd.DataFrame,
    robot: RobotModel,
    method: str = DEFAULT_METHOD,
    joints: Sequence[int] | None = None,
    noise: NoiseModel | None = None,
    **options,
) -> IdentificationResult:
    """Identify from the tidy SI table (:mod:`analysis.identification.measurements`).

    See :func:`identify`.
    """
    return identify(robot, to_arrays(table), method=method, joints=joints, noise=noise,
                    **options)
