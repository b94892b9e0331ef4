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
    (:mod:`analysis.identification.estimators.exact_model`), started from OLS, with step halving.
    The
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
from analysis.identification.checks.data import check_identifiable, check_tests
from analysis.identification.checks.outliers import (
    flag_problem_outliers,
    outlier_threshold,
    outlier_warning,
    residual_table,
    studentize,
)
from analysis.identification.io.measurements import TestArrays, to_arrays
from analysis.identification.linalg.lsq import scaled_condition
from analysis.identification.noise import NoiseModel
from analysis.identification.problem import (
    COND_LIMIT,
    DEFAULT_METHOD,
    OUTLIER_FAMILY_LEVEL,
    IdentificationProblem,
    IdentifyOptions,
)
from analysis.identification.result import IdentificationResult
from analysis.identification.streaming import per_test
from analysis.identification.streaming.covariances import component_sigmas
from analysis.model.robot_model import RobotModel
from analysis.text_format import level


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
    tests : :class:`analysis.identification.io.measurements.TestArrays` (SI).
    method : "ols", "wls" or "exact".
    joints : 0-based joints to identify (others rigid); default all six, or
        (0, 1, 2) when no rotation is measured.
    noise : instrument noise model (default :class:`NoiseModel()`).
    covariance : "model" (known sigmas) or "residual" (scaled by reduced chi-square).
    outlier_level : family-wise level of the outlier test
        (:func:`~analysis.identification.checks.outliers.outlier_threshold`).
    validate : run leave-one-pose-out validation (needs >= 3 poses).
    robust : "none" (the Gaussian fit), "huber" or "tukey": IRLS around ``method``
        (:mod:`analysis.identification.estimators.irls`). The chi-square, the noise-ratio notes
        and the validation then use the components kept (weight >= 0.5); the
        ``outlier`` column marks the ones down-weighted below it.
    holdout_radius : poses closer than this (rad, ||dq|| over the joints) are held out
        together in the validation; default
        :data:`analysis.identification.validation.holdout_check.CLUSTER_DEG` (the planner's default
        minimum separation; a run passes its protocol's).

    The options become an :class:`~analysis.identification.problem.IdentifyOptions`, and
    with the rest an :class:`~analysis.identification.problem.IdentificationProblem`
    (:func:`solve`).
    """
    options = IdentifyOptions(method=method, covariance=covariance, cond_limit=cond_limit,
                              outlier_level=outlier_level, validate=validate,
                              confidence=confidence, robust=robust,
                              holdout_radius=holdout_radius)
    return solve(IdentificationProblem.make(robot, tests, joints, noise, options))


def solve(problem: IdentificationProblem) -> IdentificationResult:
    """Identify ``problem``: check, fit, validate, the statistics, intervals and outliers."""
    from threadpoolctl import threadpool_limits

    # the work is batched 6 x 6 and tall-skinny (6000 x 7) linear algebra: a second BLAS
    # thread does not speed it up, and on a shared machine its spin-waiting costs CPU
    # (measured: TSQR of 6e5 x 7 rows 0.02-0.06 s in one thread, 0.13-0.36 s in two)
    with threadpool_limits(limits=1):
        return _solve(problem)


def _solve(problem: IdentificationProblem) -> IdentificationResult:
    """:func:`solve` in the calling thread's BLAS thread limit."""
    from analysis.identification.estimators.registry import estimator

    cond, warnings = _checked(problem)
    est = estimator(problem.options.method, problem.options.robust)
    outcome = est.fit(problem)
    if problem.large:
        per_test.release_freed_heap()  # the fit's freed pages, before the validation
    corr = None
    if est.linearised:
        # the raw prediction A x_hat let go before the correction makes f(x_c) (48 MB
        # each at 1e6 tests: one of them held at a time)
        outcome = _without_prediction(outcome)
        outcome, corr = _linear_bias(problem, outcome)
    if outcome.robust is not None:
        outcome = _with_robust_covariance(outcome)
    # validation first: a streamed exact fit's per-pose sums (and its deflections, Newton's
    # start for the held-out tests) are let go before the per-test statistics are made
    validation = _validation(problem, outcome, corr)
    if validation is not None:
        warnings += _validation_flags(validation)
    elif problem.options.validate:
        warnings.append(_no_validation_note(problem))
    outcome = _released(outcome)
    if problem.large:
        per_test.release_freed_heap()  # the blocks' freed pages, before the statistics
    from analysis.identification.checks.noise_check import noise_ratio_notes
    from analysis.identification.intervals import reported_intervals
    from analysis.identification.statistics import fit_statistics

    stats, outcome = fit_statistics(problem, outcome)
    chosen, tests = outcome.fit, problem.tests
    # (m, 6) each component's sigma; for a large campaign made where used (48 MB at 1e6)
    sigma = component_sigmas(chosen.cov)
    warnings += noise_ratio_notes((tests.d, chosen.predicted), sigma, outcome.kept,
                                  problem.noise, problem.p)
    iv = reported_intervals(problem, outcome, stats, corr)
    warnings += iv.notes
    residuals, rows, threshold, notes = _residuals(problem, outcome, stats, iv, sigma)
    warnings += notes
    return _result(problem, outcome, stats, iv, cond, residuals, rows, threshold, validation,
                   warnings)


def _with_robust_covariance(outcome):
    """``outcome`` with its robust fit's sandwich covariance made
    (:mod:`analysis.identification.estimators.robust_covariance`): its scores on the
    residuals the weights were taken from, for ols and wls the exact model's d - f(x_c) at
    the bias-corrected estimate (:func:`analysis.identification.estimators.irls._irls`;
    why: docs/identification.md, robust table)."""
    from dataclasses import replace

    return replace(outcome, robust=outcome.robust.with_covariance())


def _checked(problem: IdentificationProblem) -> tuple[float, list[str]]:
    """Refuse tests that cannot identify the joints; (condition number of the scaled
    design, the warnings of a translational-only campaign)."""
    tests, joints = problem.tests, problem.joints
    check_tests(problem.robot, tests, joints, problem.noise, group=problem.pose_group)
    problem.folds  # noqa: B018 (the validation's folds, made before the design)
    cond = check_identifiable(problem.design[1], joints, problem.options.cond_limit)
    warnings: list[str] = []
    if not tests.has_rotations and any(j >= 3 for j in joints):
        warnings.append("no rotation measured: wrist joints are identified from translations "
                        "only, expect wide intervals")
    if problem.preloaded:
        if problem.options.method == "exact":
            warnings.append("reference readings under a preload: the displacement is fitted "
                            "between the equilibria under the reference wrench and under "
                            "the loaded one (the wrench in the tables is their difference)")
        else:
            warnings.append("reference readings under a preload: the linear model in the "
                            "wrench difference w - w_ref, first order in the deflection; "
                            "the exact model (--method exact) solves both equilibria")
    if not tests.has_rotations and joints == (0, 1, 2):
        warnings.append("translational-only variant: wrist joints 4-6 taken as rigid; their "
                        "compliance, if any, is absorbed by k1..k3")
    return cond, warnings


def _without_prediction(outcome):
    """``outcome`` whose fit holds no prediction (:func:`_linear_bias` makes it again)."""
    from dataclasses import replace

    return replace(outcome, fit=replace(outcome.fit, predicted=None))


def _linear_bias(problem: IdentificationProblem, outcome):
    """(outcome, correction): the linear model's bias corrected (before the validation,
    which corrects its folds too); where reliable, the residuals (chi-square, outliers,
    notes) are those of the exact model at the corrected estimate: the new outcome's fit
    predicts f(x_c), else the linear model's A x_hat (made again here: the caller let it
    go, :func:`_without_prediction`)."""
    from dataclasses import replace

    from analysis.identification.corrections.linear_bias import (
        correct_linear_bias,
        corrected_fit,
    )
    from analysis.identification.linalg.sandwich import sandwich

    chosen = outcome.fit
    corr = correct_linear_bias(problem.robot, problem.tests, problem.joints, chosen,
                               np.sqrt(np.diag(sandwich(chosen.A, chosen.cov, chosen.bread,
                                                        chosen.Linv))),
                               problem.options.method)
    return replace(outcome, fit=corrected_fit(chosen, corr)), corr


def _validation(problem: IdentificationProblem, outcome, corr) -> pd.DataFrame | None:
    """The leave-one-pose-out table, or None (not asked, or fewer than 3 folds)."""
    if not problem.options.validate:
        return None
    from analysis.identification.validation.crossval import validate_problem

    tests, kept, rob = problem.tests, outcome.kept, outcome.robust
    # robust: validated on the components the robust fit kept (weight >= 0.5)
    valid_tests = tests if rob is None else TestArrays(
        tests.pose, tests.q, tests.w, np.where(kept, tests.d, np.nan), kept, tests.line)
    return validate_problem(problem, valid_tests,
                            full_fit=outcome.fit if rob is None else None,
                            fold_sums=outcome.sums,
                            linear_shift=None if corr is None or not corr.reliable
                            else (corr.x - corr.x_raw, corr.propagation))


def _no_validation_note(problem: IdentificationProblem) -> str:
    """Why the held-out check is missing: fewer than 3 folds of poses."""
    folds = int(np.max(problem.folds, initial=-1)) + 1
    poses = int(np.max(problem.pose_group, initial=-1)) + 1
    return (f"no held-out validation: {folds} fold(s) of poses ({poses} poses, those within "
            f"{np.degrees(problem.options.radius):g} deg of each other held out together); "
            "it needs 3 or more: nothing predicted a pose it was not fitted to")


def _released(outcome):
    """``outcome`` without what only the validation used: a streamed fit's per-fold sums
    and an exact fit's deflections (48 MB at 1e6 tests)."""
    from dataclasses import replace

    return replace(outcome, fit=replace(outcome.fit, deflection=None), sums=None)


def _residuals(problem: IdentificationProblem, outcome, stats, iv, sigma):
    """(residuals, rows, threshold, notes): the residual table (:func:`residual_table`)
    with its studentized residuals and the outliers flagged, the outlier threshold, and
    the warnings about them."""
    tests, chosen, rob = problem.tests, outcome.fit, outcome.robust
    options = problem.options
    threshold = outlier_threshold(int(tests.measured.sum()), options.outlier_level)
    t = studentize(tests, chosen.predicted, stats.var_r, iv.scale)  # in var_r's array
    if rob is None:
        bias = iv.linear_bias
        flags = flag_problem_outliers(problem, chosen, iv.scale, threshold, t,
                                      bias_se=iv.se_raw if bias is not None
                                      and bias["reliable"] else None)
    else:
        flags = tests.measured & ~outcome.kept
    if problem.large:
        per_test.release_freed_heap()  # the passes' freed pages, before the residual table
    residuals, rows = residual_table(tests, chosen, sigma, t, flags, threshold,
                                     None if rob is None else rob.weights)
    if problem.large:
        per_test.release_freed_heap()  # the ranking's freed blocks, before the checks
    notes = []
    if rob is not None:
        notes.append(rob.summary())
    else:
        note = outlier_warning(residuals, rows, flags, tests, threshold, options.outlier_level)
        if note is not None:
            notes.append(note)
    return residuals, rows, threshold, notes


def _result(problem, outcome, stats, iv, cond, residuals, rows, threshold, validation,
            warnings) -> IdentificationResult:
    """The :class:`IdentificationResult` of the stages' records."""
    tests, options = problem.tests, problem.options
    return IdentificationResult.build(
        robot=problem.robot.name, method=options.method, joints=problem.joints, x=iv.x,
        cov_x=iv.cov_x, ci=iv.ci, confidence=options.confidence,
        covariance=options.covariance, condition_number=cond,
        condition_number_weighted=float(scaled_condition(stats.Aw)), tests=tests,
        n_equations=int(tests.measured.sum()), dof=stats.dof,
        chi2_reduced=stats.chi2_reduced, p_value=stats.p_value, residuals=residuals,
        n_poses=int(problem.pose_group.max(initial=-1)) + 1,
        outlier_threshold=threshold,
        linear=outcome.linear, iterations=outcome.fit.iterations,
        noise=problem.noise, warnings=warnings, residual_rows=rows,
        wrench_eiv=iv.wrench_eiv, linear_bias=iv.linear_bias, encoder_eiv=iv.encoder,
        robust=None if outcome.robust is None else outcome.robust.describe(),
        validation=validation, pose_group=problem.pose_group,
    )


def _validation_flags(validation: pd.DataFrame, named: int = 5) -> list[str]:
    """A warning naming the held-out poses beyond the limit of the total-uncertainty check
    (:mod:`analysis.identification.validation.holdout_check`), or nothing."""
    beyond = validation[validation["beyond_limit"].to_numpy(dtype=bool)]
    if not len(beyond):
        return []
    from analysis.identification.validation.holdout_check import HOLDOUT_FAMILY_LEVEL

    worst = beyond.sort_values("rms_normalized_total", ascending=False).head(named)
    text = ", ".join(f"pose {r.held_out_pose} at {r.rms_normalized_total:.2f} (limit "
                     f"{r.limit_normalized_total:.2f}, p = {r.p_value_total:.2g})"
                     for r in worst.itertuples())
    more = f" and {len(beyond) - named} more" if len(beyond) > named else ""
    return [f"{len(beyond)} held-out pose(s) predicted worse than their total uncertainty "
            f"(noise and the refit's parameter uncertainty; Sidak, "
            f"{level(HOLDOUT_FAMILY_LEVEL)} family-wise over {len(validation)} poses): "
            f"{text}{more}; the model or the data of these poses is suspect"]



def analyze_table(
    table: pd.DataFrame,
    robot: RobotModel,
    method: str = DEFAULT_METHOD,
    joints: Sequence[int] | None = None,
    noise: NoiseModel | None = None,
    **options,
) -> IdentificationResult:
    """Identify from the tidy SI table (:mod:`analysis.identification.io.measurements`).

    See :func:`identify`.
    """
    return identify(robot, to_arrays(table), method=method, joints=joints, noise=noise,
                    **options)

