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

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.estimators.exact_model import (
    model_displacement,
    model_displacement_state,
)
from analysis.identification.estimators.fitting import (
    COND_LIMIT,
    check_identifiable,
    check_tests,
    fit,
    fit_exact,
)
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.lsq import sandwich_and_residual_variance, whitening
from analysis.identification.noise import NoiseModel, residual_covariance
from analysis.identification.poses import group_names, pose_groups, pose_tolerance
from analysis.identification.streaming.fold_sums import FoldSums, PackedSym
from analysis.identification.validation.holdout_check import (
    CLUSTER_DEG,
    PARAMETER_TERM_MAX_POSES,
    PredictiveSums,
    flag_columns,
    holdout_folds,
    predictive_statistic,
)
from analysis.model.kinematics import jacobian, jacobian_from_state
from analysis.model.robot_model import RobotModel

#: leave-one-pose-out with the exact fit refits every fold (warm-started) up to this
#: many distinct poses; beyond, each fold takes one Gauss-Newton step from the full-data
#: estimate (a full refit per pose costs ~P times the fit: hours for 1e4 poses)
EXACT_REFITS_MAX = 50
#: folds per chunk of the per-fold p x p algebra (bounds its temporaries)
FOLD_CHUNK = 8192
#: tests per sub-block of the total-uncertainty sums (their (b, 6, 6) temporaries)
SUB_BLOCK = 2000
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
    (:func:`~analysis.identification.estimators.fitting.jacobian_blocks`), if the caller has them.
    """
    if poses is None:
        poses = pose_groups(tests.q, pose_tolerance(noise))
    if group is None:
        radius = CLUSTER_DEG * np.pi / 180.0 if cluster_rad is None else cluster_rad
        group = holdout_folds(tests.q, poses, radius)
    table = _leave_out(robot, tests, method, joints, noise, batched, max_exact_refits,
                       full_fit, group, fold_sums, linear_shift, J, poses)
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


def _deg(radius: float | None) -> str:
    return f"{CLUSTER_DEG if radius is None else radius * 180.0 / np.pi:g} deg"


def _leave_out(robot, tests, method, joints, noise, batched, max_exact_refits, full_fit,
               group, fold_sums, linear_shift, J=None,
               poses=None) -> pd.DataFrame | None:
    """The table of :func:`leave_one_pose_out` over the folds ``group`` (m,) ints.

    ``batched=False`` refits from scratch for every pose (the reference path).
    ``max_exact_refits`` (default :data:`EXACT_REFITS_MAX`): with more poses than
    this, exact folds take one Gauss-Newton step from the full-data estimate.
    ``full_fit``: the :class:`analysis.identification.result.Fit` of ``method`` on all
    the tests, if the caller has it (saves refitting the full data). ``group``: the
    tests' pose groups (:func:`~analysis.identification.poses.pose_groups`) if the caller
    has them. ``fold_sums``: the per-pose sums of a streamed exact ``full_fit``
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
    names = group_names(tests.pose, group)
    if len(names) < 3:
        return None
    per_fold_correction = linear_shift is not None and len(names) <= max_exact_refits
    if per_fold_correction:
        batched = False  # each fold is refitted and corrected (the reference path)
    if batched and method == "ols":
        try:
            # row checks hold for every subset then
            check_tests(robot, tests, joints, group=poses)
        except InputError:
            batched = False
        else:
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
            table = _downdate_batched(robot, tests, group, names, joints, noise, A, rhs,
                                      np.zeros(len(joints)), method, linear_shift=shift,
                                      offset=offset)
            if linear_shift is not None:
                table["note"] = [n or SHIFT_NOTE for n in table["note"]]
            return table
    start = None
    if batched and method == "exact":
        try:
            full = full_fit if full_fit is not None else fit(robot, tests, joints, noise,
                                                             method, J=J)
            start = full.x
        except InputError:
            start = None
        if start is not None and len(names) > max_exact_refits:
            # one Gauss-Newton step per fold from the full-data estimate (module docstring)
            sums = None if fold_sums is None else fold_sums.folds
            # the residuals are only read when the folds are summed here (48 MB at 1e6)
            resid = None if sums is not None else tests.d - full.predicted
            table = _downdate_batched(robot, tests, group, names, joints, noise, full.A,
                                      resid, full.x, method, dq0=full.deflection,
                                      Linv=full.Linv, system=_system_of(full), sums=sums,
                                      shift=full.eiv_shift, J=J)
            table["note"] = [n or ONE_STEP_NOTE for n in table["note"]]
            return table
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
            pred, D = model_displacement(robot, test.q, x, test.w)
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
    return _with_total(pd.DataFrame(rows), total, lambda h: C_folds[h])


SHIFT_NOTE = ("linearisation bias of the fold corrected with the full fit's linearisation "
              f"error of each test (more than {EXACT_REFITS_MAX} poses)")


class _LessOffset:
    """``d - (f - A x_c)`` (m, 6) made a block of tests at a time when sliced: the
    displacements less the full fit's linearisation error (no (m, 6) copy)."""

    def __init__(self, d, A, f, x_c) -> None:
        self.d, self.A, self.f, self.x_c = d, A, f, x_c

    def __getitem__(self, sl):
        return self.d[sl] - (self.f[sl] - np.asarray(self.A[sl]) @ self.x_c)


def _with_total(table: pd.DataFrame, total: PredictiveSums, covariance) -> pd.DataFrame:
    """``table`` with the columns of the check against the prediction's total uncertainty
    (:func:`analysis.identification.validation.holdout_check.flag_columns`); folds without a
    prediction (NaN RMS) get NaN and no flag."""
    q = predictive_statistic(total, covariance)
    q[~np.isfinite(table["rms_normalized"].to_numpy(dtype=float))] = np.nan
    for name, col in flag_columns(q, total.n).items():
        table[name] = col
    return table


def _system_of(fit):
    """(R, c, scale) of a fit's column-scaled whitened system [Linv A / scale | Linv r] at
    its estimate, from its own factor ``fit.R`` (a streamed fit), or None.

    ``fit.R`` is the R of the unscaled system at x - eiv_shift: scaling columns scales
    R's columns (Householder QR's backward error is column-wise), and moving x by the
    shift moves Q^T Linv r by -R shift.
    """
    if getattr(fit, "R", None) is None:
        return None
    p = fit.R.shape[0] - 1
    R, c = fit.R[:p, :p], fit.R[:p, p]
    if fit.eiv_shift is not None:
        c = c - R @ fit.eiv_shift
    scale = np.linalg.norm(R, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    return R / scale, c, scale


def _downdate_batched(robot, tests, fold, labels, joints, noise, Aw, rw, x0, method,
                      dq0=None, Linv=None, system=None, sums=None, shift=None,
                      linear_shift=None, offset=None, J=None) -> pd.DataFrame:
    """Every fold's estimate from one factorisation of the full (whitened) system.

    ``Aw`` (m, 6, p) and ``rw`` (m, 6) are the design and right-hand side: for ols the
    design and the measured displacements (``x0`` = 0, the fold estimate is the exact
    least-squares refit); for exact the Jacobian and residual at the full-data estimate
    ``x0`` (one Gauss-Newton step per fold), both whitened by ``Linv`` (m, 6, 6) block by
    block (no (m, 6, p) copy). Memory is linear in the number of tests (the factor is
    built blockwise, :func:`analysis.identification.linalg.lsq.tall_r`; ``Aw`` and ``Linv`` may
    be made when sliced, :mod:`analysis.identification.streaming.per_test`). ``dq0`` (m, 6): the
    full-data fit's joint deflections (rad), Newton's start for the held-out tests.
    ``system``: (R, c, scale) of the column-scaled whitened system if the caller has it
    (:func:`_system_of`: two passes saved), and ``sums`` the per-fold sums of the
    whitened system at x0 - ``shift`` (:class:`FoldSums` of a :class:`FinalPassSums`:
    no pass over the tests for the folds' estimates; with ``system``; their ``held`` and
    ``score`` are released once used). Each fold's
    estimate is then corrected for the
    wrench noise in the regressor like the fits
    (:mod:`analysis.identification.corrections.wrench_eiv`), with
    the fold's S and (A^T W A)^-1 (``Linv`` None for ols). ``linear_shift``: (shift, M)
    of an ols fit's linearisation-bias correction, added to every fold's estimate (the
    prediction is then the exact model's, and the folds' covariances are M C M^T).
    ``offset``: (f (m, 6), x_c (p,)) the exact model's values of every test at the full
    corrected estimate x_c: the folds' predictions are then the linear ones plus the
    full fit's linearisation error f - A x_c (its change between x_c and a fold's
    estimate is second order: ~1 % of a change of ~se/x) instead of the model's.
    ``J``: the tests' Jacobians if the caller has them.

    The folds' covariances for the total-uncertainty check: (A^T W A)_-h^-1 for a fit
    whitened by its own covariances, the sandwich bread_-h meat_-h bread_-h for ols
    (meat summed per fold in the prediction pass).
    """
    from scipy.linalg import solve_triangular

    from analysis.identification.estimators.fitting import jacobian_blocks
    from analysis.identification.linalg.lsq import TEST_BLOCK, TallR

    cols = list(joints)
    m, p = Aw.shape[0], Aw.shape[-1]
    P = len(labels)  # fold: the pose group of each test, as in the reference path

    def design(sl):  # (b, 6, p) rows of the (whitened) design
        return Aw[sl] if Linv is None else Linv[sl] @ Aw[sl]

    def rhs(sl):  # (b, 6) the (whitened) right-hand side, 0 where not measured
        r = np.where(tests.measured[sl], rw[sl], 0.0)
        return r if Linv is None else np.einsum("mij,mj->mi", Linv[sl], r)

    blocks = [slice(s, s + TEST_BLOCK) for s in range(0, m, TEST_BLOCK)]
    if system is None:
        scale = np.sqrt(sum(np.sum(design(sl).reshape(-1, p) ** 2, axis=0) for sl in blocks))
        scale = np.where(scale > 0, scale, 1.0)
        acc = TallR()
        for sl in blocks:
            acc.add(np.column_stack([design(sl).reshape(-1, p) / scale, rhs(sl).reshape(-1)]))
        Rc = acc.r()
        R, c = Rc[:p, :p], Rc[:p, p]
    else:
        R, c, scale = system
    if sums is not None:
        # U = (Linv A / scale) R^-1 summed per fold from the sums of (Linv A)^T (Linv A)
        # and (Linv A)^T Linv r at x0 - shift (r moves by -A shift to x0), packed as upper
        # triangles; S is made chunk by chunk of folds where used, never held whole
        Rinv = np.linalg.inv(R) * (1.0 / scale)[:, None]  # D^-1 R^-1
        gram = PackedSym(sums.gram, p)
        t = np.empty((P, p))
        for s in range(0, P, FOLD_CHUNK):
            h = np.arange(s, min(s + FOLD_CHUNK, P))
            score = sums.score[h] if shift is None else sums.score[h] - gram.chunk(h) @ shift
            t[h] = score @ Rinv
        S = _Congruent(gram, Rinv)
        held = PackedSym(sums.held, p)
    else:
        # U = (Linv A / scale) R^-1 per test, summed per fold in one pass, with the folds'
        # part of the wrench errors-in-variables S
        J = jacobian_blocks(robot, tests.q) if J is None else J
        sig2 = noise.wrench_sigma_at(tests.w) ** 2
        sums = FoldSums(P, cols)
        for sl in blocks:
            Ab = design(sl)
            U = solve_triangular(R, (Ab.reshape(-1, p) / scale).T, trans="T").T.reshape(
                Ab.shape)
            sums.add(fold[sl], J[sl], None if Linv is None else Linv[sl],
                     tests.measured[sl], sig2[sl], U, rhs(sl))
        S, t, held = PackedSym(sums.gram, p), sums.score, PackedSym(sums.held, p)
    lev = np.empty(P)  # largest leverage of each pose block
    for s in range(0, P, FOLD_CHUNK):
        with np.errstate(divide="ignore", invalid="ignore"):
            lev[s:s + FOLD_CHUNK] = np.linalg.eigvalsh(
                S[np.arange(s, min(s + FOLD_CHUNK, P))])[:, -1]
    ok = lev < 1.0 - 1e-10
    # Training-set condition of the column-scaled A without forming it: its Gram matrix
    # is R^T (I - S_h) R = M_h^T M_h with M_h = chol(I - S_h)^T R (p x p); in chunks of
    # folds ((P, p, p) temporaries are 29 MB each at 1e5 poses)
    cond = np.full(P, np.inf)
    good = np.flatnonzero(ok)
    for s in range(0, len(good), FOLD_CHUNK):
        h = good[s:s + FOLD_CHUNK]
        M = np.swapaxes(np.linalg.cholesky(np.eye(p) - S[h]), -1, -2) @ R
        norms = np.linalg.norm(M, axis=-2)
        sv = np.linalg.svd(M / np.where(norms > 0, norms, 1.0)[:, None, :], compute_uv=False)
        with np.errstate(divide="ignore"):
            cond[h] = np.where(np.all(norms > 0, axis=-1), sv[:, 0] / sv[:, -1], np.inf)
    # Per-fold refusals of the reference path that depend on the training subset.
    n_eq = int(tests.measured.sum()) - np.bincount(fold, tests.measured.sum(axis=1), P)
    # folds are whole pose groups, so every training set keeps P - 1 >= 2 distinct poses
    suspect = ~ok | (cond > COND_LIMIT) | (n_eq < p)
    notes = [""] * P
    for h in np.flatnonzero(suspect):
        # the reference path's own checks give the message (and the verdict)
        train = fold != h
        try:
            check_tests(robot, tests.subset(train), joints)
            sub = tests.subset(train)
            A = design_block(jacobian(robot, sub.q), sub.w)[..., cols] * sub.measured[..., None]
            check_identifiable(A, joints)
        except InputError as err:
            notes[h], ok[h] = str(err), False
            continue
        if not ok[h]:
            notes[h] = "the other poses cannot identify the compliances (leverage 1)"
    z = np.zeros((P, p))
    good = np.flatnonzero(ok)
    for s in range(0, len(good), FOLD_CHUNK):
        h = good[s:s + FOLD_CHUNK]
        z[h] = np.linalg.solve(np.eye(p) - S[h], (c - t[h])[..., None])[..., 0]
    x_p = x0 + solve_triangular(R, z.T).T / scale  # (P, p)
    x_p[ok] = _fold_eiv(held, R, scale, S, x_p, ok)
    # the folds' scores and errors-in-variables parts are used up (17 + 5 MB at 1e5 poses):
    # let them go before the prediction pass (the folds' Gram matrices stay, in S)
    held = t = None
    sums.held = sums.score = None
    if linear_shift is not None:
        x_p = x_p + linear_shift[0]
    exact_model = method == "exact" or (linear_shift is not None and offset is None)
    x = np.zeros((P, 6))
    x[:, cols] = x_p
    if P > PARAMETER_TERM_MAX_POSES:
        # the refit's parameter term is below 1/P of the noise term: left out
        total, meat = PredictiveSums(P, p, parameter=False), None
    elif Linv is not None:
        # a fit whitened by its own covariances: the held-out poses' F^T W F are the
        # folds' parts of its normal matrix, D R^T S_h R D (no per-fold sums of their own)
        def normal(h):
            return scale[:, None] * (R.T @ S[h] @ R) * scale[None, :]

        total = PredictiveSums(P, p, normal=normal)
        meat = None
    else:  # ols: A^T Sigma A per fold for the sandwich (float32: 8 MB at 1e5 poses)
        total = PredictiveSums(P, p)
        meat = np.zeros((P, len(total.iu[0])), dtype=np.float32)
    # held-out prediction errors, summed per fold (test blocks bound the memory)
    sq = np.zeros((3, P))  # squared errors: translation, rotation, normalised
    failed = np.zeros(P, dtype=bool)
    for s in range(0, m, TEST_BLOCK):
        sl = slice(s, s + TEST_BLOCK)
        f, q, w, meas = fold[sl], tests.q[sl], tests.w[sl], tests.measured[sl]
        xt = x[f]  # the held-out estimate used for each test
        if exact_model:
            unloaded: dict = {}
            pred, _, good, _ = model_displacement_state(
                robot, q, xt, w, with_jacobian=False, dq0=None if dq0 is None else dq0[sl],
                unloaded=unloaded)
            J = jacobian_from_state(unloaded["state"])  # J(q), from the model's own state
            failed |= np.bincount(f, ~good, P) > 0
        else:
            J = jacobian(robot, q)
        # the linear model's A for F of the prediction's parameter term also for the exact
        # model (their difference, ~1 % of the deflection, moves that term by ~1 %; the
        # model's Jacobian would cost its derivatives for every test)
        F = design_block(J, w)[..., cols]
        if not exact_model:
            pred = np.einsum("mrj,mj->mr", F, x_p[f])
            if offset is not None:  # + the linearisation error at the full estimate
                pred += offset[0][sl] - F @ offset[1]
        err = np.where(meas, tests.d[sl] - pred, 0.0)
        C = (J * xt[:, None, :]) @ np.swapaxes(J, -1, -2)  # J diag(x) J^T
        cov_t = residual_covariance(noise, C, w)
        sig = np.sqrt(np.diagonal(cov_t, axis1=-2, axis2=-1))
        for u in range(0, len(f), SUB_BLOCK):  # the check's per-test temporaries: small
            v = slice(u, u + SUB_BLOCK)
            total.add(f[v], whitening(cov_t[v], meas[v]), F[v], err[v], meas[v])
            if meat is not None:  # ols: A^T Sigma A of the tests, per fold
                Ab = np.where(meas[v][..., None], F[v], 0.0)
                AtSA = np.einsum("mri,mrs,msj->mij", Ab, cov_t[v], Ab)[:, total.iu[0],
                                                                       total.iu[1]]
                for a in range(AtSA.shape[1]):
                    meat[:, a] += np.bincount(f[v], AtSA[:, a], P)
        sq[0] += np.bincount(f, np.sum(err[:, :3] ** 2, axis=1), P)
        sq[1] += np.bincount(f, np.sum(err[:, 3:] ** 2, axis=1), P)
        sq[2] += np.bincount(f, np.sum((err / sig) ** 2, axis=1), P)
    counts = np.stack([np.bincount(fold, tests.measured[:, :3].sum(axis=1), P),
                       np.bincount(fold, tests.measured[:, 3:].sum(axis=1), P),
                       np.bincount(fold, tests.measured.sum(axis=1), P)])
    with np.errstate(divide="ignore", invalid="ignore"):
        rms = np.where(counts > 0, np.sqrt(sq / np.where(counts > 0, counts, 1)), np.nan)
    for h in np.flatnonzero(ok & failed):
        ok[h] = False
        notes[h] = ("the equilibrium has no solution at this fold's estimate for a held-out "
                    "test (wrench too large for these compliances)")
    rms[:, ~ok] = np.nan
    table = pd.DataFrame({
        "held_out_pose": list(labels),
        "n_tests": np.bincount(fold, minlength=P).astype(int),
        "rms_translation_m": rms[0], "rms_rotation_rad": rms[1], "rms_normalized": rms[2],
        "note": notes,
    })
    Rinv = np.linalg.inv(R)
    meat_total = None if meat is None else PackedSym(meat.astype(float), p).total()

    def covariance(h):  # the folds' covariances (len(h), p, p), NaN for folds not fitted
        with np.errstate(all="ignore"):
            bread = (Rinv @ np.linalg.solve(np.eye(p) - S[h], np.broadcast_to(
                Rinv.T, (len(h), p, p)))) / (scale[:, None] * scale[None, :])
        if meat is not None:
            bread = bread @ (meat_total - PackedSym(meat, p)[h].astype(float)) @ bread
        if linear_shift is not None:
            bread = linear_shift[1] @ bread @ linear_shift[1].T
        bread[~ok[h]] = np.nan
        return bread

    return _with_total(table, total, covariance)


class _Congruent:
    """B^T G_h B for folds h, from per-fold G (:class:`PackedSym`), made when indexed."""

    def __init__(self, G: PackedSym, B: np.ndarray) -> None:
        self.G, self.B = G, B

    def __getitem__(self, h) -> np.ndarray:
        return self.B.T @ self.G.chunk(h) @ self.B


def _fold_eiv(held, R, scale, lev, x_p, ok):
    """The folds' estimates x_p[ok] (n_ok, p) corrected for the wrench errors in variables.

    Fold h's normal matrix is ``D R^T (I - lev_h) R D`` (D = diag(scale)) and its S the
    full S less the held-out tests' part ``held`` (P, p, p).
    """
    from analysis.identification.corrections.wrench_eiv import corrected

    p = R.shape[0]
    Rinv = np.linalg.inv(R)
    total = held.total() if isinstance(held, PackedSym) else held.sum(axis=0)
    folds = np.flatnonzero(ok)
    x_c = np.empty((len(folds), p))
    for s in range(0, len(folds), FOLD_CHUNK):  # (folds, p, p) temporaries: chunks
        h = folds[s:s + FOLD_CHUNK]
        bread = (Rinv @ np.linalg.solve(np.eye(p) - lev[h], np.broadcast_to(
            Rinv.T, (len(h), p, p)))) / (scale[:, None] * scale[None, :])
        x_c[s:s + FOLD_CHUNK], _ = corrected(x_p[h], bread, total - held[h])
    return x_c
