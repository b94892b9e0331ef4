"""Validation by prediction on held-out poses (leave one pose out).

Each distinct pose in turn (tests at joint angles equal to within the encoder
noise, :mod:`analysis.identification.poses`, named by their labels) is removed,
the joint compliances are identified from the other tests with the same estimator, and the held-out
displacements are predicted (linear model for ols/wls, exact equilibrium for
exact). Reported per held-out pose: RMS prediction error of the translations
(m) and rotations (rad), and the RMS of the errors divided by the
measurement sigma (about 1 for a model that predicts to within the noise;
somewhat more because the estimate itself is uncertain).

For ols the refits are one batched computation: with the thin QR ``A = Q R``
of the full stacked design and ``U = A R^-1``, removing the rows H of a pose
gives ``x_-H = R^-1 (I - U_H^T U_H)^-1 (Q^T d - U_H^T d_H)``: a p x p solve per
pose (its conditioning is that of the pose's leverage, not A's squared). For
exact, each refit starts from the full-data estimate (warm start); with more
than :data:`EXACT_REFITS_MAX` distinct poses each fold instead takes one
Gauss-Newton step from the full-data estimate x: the same downdate applied to
the whitened Jacobian F_w and residual r_w at x,
``x_-H = x + R^-1 (I - U_H^T U_H)^-1 (Q^T r_w - U_H^T r_wH)`` (the fold's cost is
quadratic in the step up to the model's curvature, which is ~1 % of the
deflection, so the step lands within a small fraction of the fold's
uncertainty of the refit; the table's note says so). Both paths hold
memory linear in the number of tests (factors built blockwise, per-fold sums
by bincount).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.checks.data import check_identifiable, check_tests
from analysis.identification.estimators.exact_model import (
    model_displacement,
)
from analysis.identification.estimators.fit_solvers import fit, fit_exact
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import whitening
from analysis.identification.linalg.sandwich import sandwich_and_residual_variance
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.poses import group_names, pose_groups, pose_tolerance
from analysis.identification.validation.downdate import downdate_folds, system_of, with_total
from analysis.identification.validation.folds import Folds
from analysis.identification.validation.holdout_check import (
    CLUSTER_DEG,
    PredictiveSums,
    holdout_folds,
)
from analysis.model.kinematics import jacobian
from analysis.model.robot_model import RobotModel

if TYPE_CHECKING:
    from analysis.identification.problem import IdentificationProblem

#: leave-one-pose-out with the exact fit refits every fold (warm-started) up to this
#: many distinct poses; beyond, each fold takes one Gauss-Newton step from the full-data
#: estimate (a full refit per pose costs ~P times the fit: hours for 1e4 poses)
EXACT_REFITS_MAX = 50
ONE_STEP_NOTE = ("one Gauss-Newton step from the full-data estimate (more than "
                 f"{EXACT_REFITS_MAX} poses)")


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def leave_one_pose_out(
    robot: RobotModel,
    tests: TestArrays,
    method: str,
    joints: tuple[int, ...],
    noise: NoiseModel,
    batched: bool = True,
    max_exact_refits: int | None = None,
    full_fit=None,
    group: np.ndarray | None = None,
    fold_sums=None,
    linear_shift: tuple[np.ndarray, np.ndarray] | None = None,
    cluster_rad: float | None = None,
    poses: np.ndarray | None = None,
    J=None,
) -> pd.DataFrame | None:
    """Table of held-out prediction errors, or None with fewer than 3 folds.

    The folds are the poses, those within ``cluster_rad`` (rad, ||dq|| over the joints;
    default :data:`~analysis.identification.validation.holdout_check.CLUSTER_DEG`) of each other
    held out together (:func:`~analysis.identification.validation.holdout_check.holdout_folds`);
    ``group``: the folds if the caller has them (:func:`holdout_folds` of the poses).
    Columns ``poses_held_out`` (poses in the fold) and a note where it is more than one;
    ``held_out_pose`` names the fold by its labels joined with '+'. See
    :func:`_leave_out` for the rest. ``poses``: the tests' pose groups
    (:func:`~analysis.identification.poses.pose_groups`) and ``J`` their Jacobians
    (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`), if the caller has
    them.
    """
    if poses is None:
        poses = pose_groups(tests.q, pose_tolerance(noise))
    if group is None:
        radius = CLUSTER_DEG * np.pi / 180.0 if cluster_rad is None else cluster_rad
        group = holdout_folds(tests.q, poses, radius)
    folds = Folds(robot, tests, method, tuple(joints), noise, group, poses,
                   group_names(tests.pose, group), J)
    table = _leave_out(folds, batched, max_exact_refits, full_fit, fold_sums, linear_shift)
    if table is None:
        return None
    # poses per fold: distinct (fold, pose) pairs counted per fold (one each when there
    # are as many folds as poses: folds are unions of poses)
    n_folds = int(group.max(initial=-1)) + 1
    n_poses = int(poses.max(initial=-1)) + 1
    if n_folds == n_poses:
        count = np.ones(n_folds, dtype=int)
    else:
        pairs = np.unique(group.astype(np.int64) * n_poses + poses)
        count = np.bincount(pairs // n_poses, minlength=n_folds)
    table["poses_held_out"] = count.astype(int)
    table["note"] = [
        "; ".join(t for t in (n, f"{c} poses within {_deg(cluster_rad)} of each other held "
                              "out together") if t) if c > 1 else n
        for n, c in zip(table["note"], count, strict=True)]
    return table


def validate_problem(problem: IdentificationProblem, tests: TestArrays | None = None,
                     full_fit=None, fold_sums=None,
                     linear_shift: tuple[np.ndarray, np.ndarray] | None = None
                     ) -> pd.DataFrame | None:
    """:func:`leave_one_pose_out` of an identification ``problem``, taken whole: its robot,
    method, joints, noise, held-out folds and radius, pose groups and Jacobians. ``tests``:
    the tests validated on (default the problem's; a robust fit's kept components);
    ``full_fit``, ``fold_sums``, ``linear_shift`` as there."""
    return leave_one_pose_out(problem.robot, problem.tests if tests is None else tests,
                              problem.options.method, problem.joints, problem.noise,
                              full_fit=full_fit, group=problem.folds,
                              cluster_rad=problem.options.radius, poses=problem.pose_group,
                              J=problem.jacobian, fold_sums=fold_sums,
                              linear_shift=linear_shift)


def _deg(radius: float | None) -> str:
    return f"{CLUSTER_DEG if radius is None else radius * 180.0 / np.pi:g} deg"


def _leave_out(folds: Folds, batched, max_exact_refits, full_fit, fold_sums,
               linear_shift) -> pd.DataFrame | None:
    """The table of :func:`leave_one_pose_out` over the folds ``folds.group`` (m,) ints.

    ``batched=False`` refits from scratch for every pose (the reference path).
    ``max_exact_refits`` (default :data:`EXACT_REFITS_MAX`): with more poses than
    this, exact folds take one Gauss-Newton step from the full-data estimate.
    ``full_fit``: the :class:`analysis.identification.estimators.fit_record.Fit` of
    ``method`` on all the tests, if the caller has it (saves refitting the full data).
    ``fold_sums``: the per-pose sums of a streamed exact ``full_fit``
    (:class:`~analysis.identification.streaming.fold_sums.FinalPassSums`, made in its
    final pass).
    ``linear_shift``: for ols/wls whose linearisation bias was corrected
    (:mod:`analysis.identification.corrections.linear_bias`), (shift, M) of the full-data correction
    (x_c - x_hat (p,), and its propagation (p, p)): each fold's estimate is then
    corrected too and predicted with the exact model -- by its own correction up to
    :data:`EXACT_REFITS_MAX` poses, beyond by the full-data shift (the note says so).

    Besides the RMS errors and ``rms_normalized`` (errors over the measurement sigma),
    each pose gets the check against the prediction's total uncertainty (noise plus the
    refit's parameter uncertainty) and its flag
    (:mod:`analysis.identification.validation.holdout_check`).
    """
    if max_exact_refits is None:
        max_exact_refits = EXACT_REFITS_MAX
    if len(folds.names) < 3:
        return None
    per_fold_correction = linear_shift is not None and len(folds.names) <= max_exact_refits
    if per_fold_correction:
        batched = False  # each fold is refitted and corrected (the reference path)
    if batched and folds.method == "ols":
        table = _batched_ols(folds, full_fit, linear_shift)
        if table is not None:
            return table
    start = None
    if batched and folds.method == "exact":
        start, table = _batched_exact(folds, full_fit, fold_sums, max_exact_refits)
        if table is not None:
            return table
    return _refit_each(folds, start, linear_shift)


def _batched_ols(folds: Folds, full_fit, linear_shift) -> pd.DataFrame | None:
    """Every OLS fold by downdates of the full system (:func:`downdate_folds`), or None
    when the row checks refuse the tests (the reference path then names the folds)."""
    robot, tests, joints, poses = folds.robot, folds.tests, folds.joints, folds.poses
    try:
        # row checks hold for every subset then
        check_tests(robot, tests, joints, group=poses)
    except InputError:
        return None
    if full_fit is not None and full_fit.Linv is None:
        A = full_fit.A  # the OLS fit's design: the same array (no second copy)
    else:
        J = jacobian(robot, tests.q)
        A = design_block(J, tests.w)[..., list(joints)] * tests.measured[..., None]
    offset, rhs, shift = None, tests.d, linear_shift
    if linear_shift is not None and full_fit is not None:
        # the full fit's linearisation error of each test, e = f(x_c) - A x_c (its
        # prediction is f(x_c) once corrected): each fold's least squares of d - e
        # is its own estimate less its own bias G_h e (to first order), and its
        # prediction A x_h + e; no model evaluation per fold
        offset = (full_fit.predicted, full_fit.x + linear_shift[0])
        rhs = _LessOffset(tests.d, A, *offset)
        shift = (np.zeros(len(joints)), linear_shift[1])
    table = downdate_folds(folds, A, rhs, np.zeros(len(joints)), linear_shift=shift,
                           offset=offset)
    if linear_shift is not None:
        table["note"] = [n or SHIFT_NOTE for n in table["note"]]
    return table


def _batched_exact(folds: Folds, full_fit, fold_sums, max_exact_refits):
    """(start, table): the full-data exact estimate (None when it cannot be fitted) and,
    with more than ``max_exact_refits`` poses, every fold by one Gauss-Newton step from
    it (:func:`downdate_folds`), else None (each fold is refitted from ``start``)."""
    robot, tests, joints, noise, J = folds.robot, folds.tests, folds.joints, folds.noise, \
        folds.J
    start = None
    try:
        full = full_fit if full_fit is not None else fit(robot, tests, joints, noise,
                                                         folds.method, J=J)
        start = full.x
    except InputError:
        start = None
    if start is not None and len(folds.names) > max_exact_refits:
        # one Gauss-Newton step per fold from the full-data estimate (module docstring)
        sums = None if fold_sums is None else fold_sums.folds
        # the residuals are only read when the folds are summed here (48 MB at 1e6)
        resid = None if sums is not None else tests.d - full.predicted
        table = downdate_folds(folds, full.A, resid, full.x, dq0=full.deflection,
                               Linv=full.Linv, system=system_of(full), sums=sums,
                               shift=full.eiv_shift)
        table["note"] = [n or ONE_STEP_NOTE for n in table["note"]]
        return start, table
    return start, None


def _refit_each(folds: Folds, start, linear_shift) -> pd.DataFrame:
    """The reference path: every fold refitted (exact: from ``start`` when given) and its
    held-out tests predicted; a fold that cannot be fitted gets its refusal as note."""
    robot, tests, group, names = folds.robot, folds.tests, folds.group, folds.names
    joints, noise, method = folds.joints, folds.noise, folds.method
    rows = []
    cols = list(joints)
    p = len(cols)
    total = PredictiveSums(len(names), p)
    C_folds = np.full((len(names), p, p), np.nan)
    for g, label in enumerate(names):
        held = group == g
        train, test = tests.subset(~held), tests.subset(held)
        row = {"held_out_pose": label, "n_tests": int(held.sum())}
        note = ""
        try:
            check_tests(robot, train, joints, noise)
            J = jacobian(robot, train.q)
            A = design_block(J, train.w)[..., cols] * train.measured[..., None]
            check_identifiable(A, joints)
            if start is not None:
                f_fold = fit_exact(robot, train, joints, noise, start)
            else:
                f_fold = fit(robot, train, joints, noise, method)
            x_p = f_fold.x
            C_fold, _ = sandwich_and_residual_variance(f_fold.A, f_fold.cov, f_fold.bread,
                                                       f_fold.Linv)
            exact_model = method == "exact"
            if linear_shift is not None:
                from analysis.identification.corrections.linear_bias import correct_linear_bias

                corr = correct_linear_bias(robot, train, joints, f_fold,
                                           np.sqrt(np.diag(C_fold)), method)
                if corr.reliable:
                    x_p, exact_model = corr.x, True
                    C_fold = corr.propagation @ C_fold @ corr.propagation.T
                else:
                    note = f"fold's linearisation bias not corrected: {corr.reason}"
        except InputError as err:
            rows.append({**row, "rms_translation_m": np.nan, "rms_rotation_rad": np.nan,
                         "rms_normalized": np.nan, "note": str(err)})
            continue
        x = np.zeros(6)
        x[cols] = x_p
        Jt = jacobian(robot, test.q)
        if exact_model:
            pred, D = model_displacement(robot, test.q, x, test.w, w_ref=test.w_ref)
            F = D[..., cols]
        else:
            F = design_block(Jt, test.w)[..., cols]
            pred = F @ x_p
        err = np.where(test.measured, test.d - pred, np.nan)
        C = np.einsum("...ij,j,...kj->...ik", Jt, x, Jt)
        cov_t = residual_covariance(noise, C, test.w)
        sig = np.sqrt(np.diagonal(cov_t, axis1=-2, axis2=-1))
        norm = err / sig
        total.add(np.full(test.m, g), whitening(cov_t, test.measured), F, err, test.measured)
        C_folds[g] = C_fold
        rows.append({
            **row,
            "rms_translation_m": _rms(err[:, :3][test.measured[:, :3]]),
            "rms_rotation_rad": _rms(err[:, 3:][test.measured[:, 3:]]),
            "rms_normalized": _rms(norm[test.measured]),
            "note": note,
        })
    return with_total(pd.DataFrame(rows), total, lambda h: C_folds[h])


SHIFT_NOTE = ("linearisation bias of the fold corrected with the full fit's linearisation "
              f"error of each test (more than {EXACT_REFITS_MAX} poses)")


class _LessOffset:
    """``d - (f - A x_c)`` (m, 6) made a block of tests at a time when sliced: the
    displacements less the full fit's linearisation error (no (m, 6) copy)."""

    def __init__(self, d, A, f, x_c) -> None:
        self.d, self.A, self.f, self.x_c = d, A, f, x_c

    def __getitem__(self, sl):
        return self.d[sl] - (self.f[sl] - np.asarray(self.A[sl]) @ self.x_c)


