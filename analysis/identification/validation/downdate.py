"""Every fold's estimate from one factorisation of the full system (batched downdates).

Leave-one-pose-out of many poses without a refit per pose: the full (whitened) system is
factorised once, and each fold's estimate, covariance and prediction of its held-out
tests follow from per-fold sums of its rows (:func:`downdate_folds`): exactly the
least-squares refit for ols, one Gauss-Newton step from the full-data estimate for
exact. :mod:`analysis.identification.validation.crossval` chooses between this and
refitting every fold.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from analysis.errors import InputError
from analysis.identification.checks.data import COND_LIMIT, check_identifiable, check_tests
from analysis.identification.estimators.exact_model import model_displacement_state
from analysis.identification.estimators.linear_model import design_block
from analysis.identification.linalg.lsq import whitening
from analysis.identification.noise import residual_covariance
from analysis.identification.streaming.fold_sums import FoldSums, PackedSym
from analysis.identification.validation.holdout_check import (
    PARAMETER_TERM_MAX_POSES,
    PredictiveSums,
    flag_columns,
    predictive_statistic,
)
from analysis.model.kinematics import jacobian, jacobian_from_state

#: folds per chunk of the per-fold p x p algebra (bounds its temporaries)
FOLD_CHUNK = 8192
#: tests per sub-block of the total-uncertainty sums (their (b, 6, 6) temporaries)
SUB_BLOCK = 2000

def with_total(table: pd.DataFrame, total: PredictiveSums, covariance) -> pd.DataFrame:
    """``table`` with the columns of the check against the prediction's total uncertainty
    (:func:`analysis.identification.validation.holdout_check.flag_columns`); folds without a
    prediction (NaN RMS) get NaN and no flag."""
    q = predictive_statistic(total, covariance)
    q[~np.isfinite(table["rms_normalized"].to_numpy(dtype=float))] = np.nan
    for name, col in flag_columns(q, total.n).items():
        table[name] = col
    return table


def system_of(fit):
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


def downdate_folds(folds, Aw, rw, x0, dq0=None, Linv=None, system=None, sums=None,
                   shift=None, linear_shift=None, offset=None) -> pd.DataFrame:
    """Every fold's estimate from one factorisation of the full (whitened) system.

    ``folds``: the fit validated and its folds
    (:class:`~analysis.identification.validation.folds.Folds`: robot, tests, method,
    joints, noise, each test's fold, the folds' labels, the tests' Jacobians).

    ``Aw`` (m, 6, p) and ``rw`` (m, 6) are the design and right-hand side: for ols the
    design and the measured displacements (``x0`` = 0, the fold estimate is the exact
    least-squares refit); for exact the Jacobian and residual at the full-data estimate
    ``x0`` (one Gauss-Newton step per fold), both whitened by ``Linv`` (m, 6, 6) block by
    block (no (m, 6, p) copy). Memory is linear in the number of tests (the factor is
    built blockwise, :func:`analysis.identification.linalg.lsq.tall_r`; ``Aw`` and ``Linv`` may
    be made when sliced, :mod:`analysis.identification.streaming.per_test`). ``dq0`` (m, 6): the
    full-data fit's joint deflections (rad), Newton's start for the held-out tests.
    ``system``: (R, c, scale) of the column-scaled whitened system if the caller has it
    (:func:`system_of`: two passes saved), and ``sums`` the per-fold sums of the
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

    The folds' covariances for the total-uncertainty check: (A^T W A)_-h^-1 for a fit
    whitened by its own covariances, the sandwich bread_-h meat_-h bread_-h for ols
    (meat summed per fold in the prediction pass).
    """
    from scipy.linalg import solve_triangular

    from analysis.identification.linalg.lsq import TEST_BLOCK

    robot, tests, fold, labels = folds.robot, folds.tests, folds.group, folds.names
    joints, noise, method, J = folds.joints, folds.noise, folds.method, folds.J
    cols = list(joints)
    m, p = Aw.shape[0], Aw.shape[-1]
    P = len(labels)  # fold: the pose group of each test, as in the reference path

    def design(sl):  # (b, 6, p) rows of the (whitened) design
        return Aw[sl] if Linv is None else Linv[sl] @ Aw[sl]

    def rhs(sl):  # (b, 6) the (whitened) right-hand side, 0 where not measured
        r = np.where(tests.measured[sl], rw[sl], 0.0)
        return r if Linv is None else np.einsum("mij,mj->mi", Linv[sl], r)

    blocks = [slice(s, s + TEST_BLOCK) for s in range(0, m, TEST_BLOCK)]
    R, c, scale = _full_system(design, rhs, blocks, p) if system is None else system
    S, t, held, sums = _per_fold(robot, tests, fold, noise, cols, R, scale, P, design, rhs,
                                 blocks, sums, shift, Linv, J)
    ok, notes = _fitted_folds(robot, tests, fold, joints, S, R, P)
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
    total, meat = _predictive_sums(P, p, Linv, S, R, scale)
    sq, failed = _prediction_pass(robot, tests, fold, noise, cols, x_p, P, exact_model, dq0,
                                  offset, total, meat)
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

    return with_total(table, total, covariance)


def _full_system(design, rhs, blocks, p):
    """(R, c, scale): the R of the column-scaled whitened system [design / scale | rhs]
    by blockwise TSQR, its last column c, and the column scale (p,)."""
    from analysis.identification.linalg.lsq import TallR

    scale = np.sqrt(sum(np.sum(design(sl).reshape(-1, p) ** 2, axis=0) for sl in blocks))
    scale = np.where(scale > 0, scale, 1.0)
    acc = TallR()
    for sl in blocks:
        acc.add(np.column_stack([design(sl).reshape(-1, p) / scale, rhs(sl).reshape(-1)]))
    Rc = acc.r()
    return Rc[:p, :p], Rc[:p, p], scale


def _per_fold(robot, tests, fold, noise, cols, R, scale, P, design, rhs, blocks, sums,
              shift, Linv, J):
    """(S, t, held, sums): per fold, S_h = U_h^T U_h of U = (Linv A / scale) R^-1 (its
    leverage matrix), t_h = U_h^T (Linv r) and the fold's part of the wrench
    errors-in-variables S; from a streamed fit's final-pass ``sums`` when given, else in
    one pass over the tests."""
    from scipy.linalg import solve_triangular

    from analysis.identification.estimators.linear_model import jacobian_blocks

    p = len(cols)
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
        return _Congruent(gram, Rinv), t, PackedSym(sums.held, p), sums
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
    return PackedSym(sums.gram, p), sums.score, PackedSym(sums.held, p), sums


def _fitted_folds(robot, tests, fold, joints, S, R, P):
    """(ok (P,) bool, notes): the folds whose training set can be fitted, and the reason
    for each that cannot (the reference path's own refusals, or leverage 1)."""
    p = len(joints)
    cols = list(joints)
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
    return ok, notes


def _predictive_sums(P, p, Linv, S, R, scale):
    """(total, meat): the per-fold sums of the total-uncertainty check
    (:class:`~analysis.identification.validation.holdout_check.PredictiveSums`) and, for
    ols, the per-fold A^T Sigma A of the sandwich (float32, packed), else None."""
    if P > PARAMETER_TERM_MAX_POSES:
        # the refit's parameter term is below 1/P of the noise term: left out
        return PredictiveSums(P, p, parameter=False), None
    if Linv is not None:
        # a fit whitened by its own covariances: the held-out poses' F^T W F are the
        # folds' parts of its normal matrix, D R^T S_h R D (no per-fold sums of their own)
        def normal(h):
            return scale[:, None] * (R.T @ S[h] @ R) * scale[None, :]

        return PredictiveSums(P, p, normal=normal), None
    # ols: A^T Sigma A per fold for the sandwich (float32: 8 MB at 1e5 poses)
    total = PredictiveSums(P, p)
    return total, np.zeros((P, len(total.iu[0])), dtype=np.float32)


def _prediction_pass(robot, tests, fold, noise, cols, x_p, P, exact_model, dq0, offset,
                     total, meat):
    """(sq (3, P), failed (P,)): the held-out prediction errors summed per fold
    (squared translation, rotation and normalised errors), and the folds where the
    equilibrium had no solution for a held-out test; ``total`` and ``meat`` are filled
    in the same pass (test blocks bound the memory)."""
    from analysis.identification.linalg.lsq import TEST_BLOCK

    m = tests.m
    x = np.zeros((P, 6))
    x[:, cols] = x_p
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
                unloaded=unloaded, w_ref=None if tests.w_ref is None else tests.w_ref[sl])
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
    return sq, failed


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
