"""Outliers: the studentized residuals, the sequential outlier test and its refits.

A residual is an outlier when its |studentized| value exceeds the Sidak threshold of the
family-wise level over all residuals (:func:`outlier_threshold`); :func:`flag_outliers`
finds them one at a time (largest first, refit after each), :func:`residual_table`
makes the residual table and its warning.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from analysis.errors import InputError
from analysis.identification.estimators.fit_record import Fit
from analysis.identification.estimators.fit_solvers import _fit_covariances, _full, fit, fit_exact
from analysis.identification.estimators.linear_model import jacobian_blocks
from analysis.identification.io.measurements import TestArrays
from analysis.identification.io.residual_rows import ResidualRows
from analysis.identification.io.results_json import RESIDUALS_LISTED
from analysis.identification.linalg.lsq import blocks_of_tests
from analysis.identification.linalg.sandwich import sandwich_and_residual_variance
from analysis.identification.problem import OUTLIER_FAMILY_LEVEL, IdentificationProblem
from analysis.identification.streaming.per_test import apply
from analysis.text_format import level


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
    return studentize(tests, f.predicted, var_r, scale)


def studentize(tests: TestArrays, predicted: np.ndarray, var_r: np.ndarray,
                scale: float) -> np.ndarray:
    """(m, 6) residuals / sqrt(scale var_r), NaN where not measured or var_r is 0, written
    into ``var_r``'s array block by block ((m, 6) arrays are 48 MB each at 1e6 tests)."""
    for sl in blocks_of_tests(tests.m, 1 << 16):
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
                  bias_se: np.ndarray | None = None, J=None) -> np.ndarray:
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
    the threshold, as one at a time. ``J``: the tests' Jacobians
    (:func:`~analysis.identification.estimators.linear_model.jacobian_blocks`) if the caller has
    them.
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
        t = None  # read again only once remade (48 MB at 1e6 tests, not held by the refit)
        keep = tests.measured & ~flags
        # d as it is: components not ``measured`` are not read (no 48 MB copy at 1e6 tests)
        rest = TestArrays(tests.pose, tests.q, tests.w, tests.d, keep, tests.line)
        try:
            current = _refit_without(robot, rest, joints, noise, method, current, i, c,
                                     tests.d[i, c], J)
            if bias_se is not None:
                from analysis.identification.corrections.linear_bias import (
                    correct_linear_bias,
                    corrected_fit,
                )

                # the refit's A x let go while the correction makes f(x_c) (one (m, 6)
                # array at a time; made again where the correction is unreliable)
                current = replace(current, predicted=None)
                current = corrected_fit(current, correct_linear_bias(
                    robot, rest, joints, current, bias_se, method))
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
                   i, c, d_ic, J=None) -> Fit:
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
    than from OLS). WLS: full refit. ``J``: the Jacobians of ``rest`` (the same joint
    angles as ``prev``'s tests) if the caller has them.
    """
    rows = list(zip(np.atleast_1d(i).tolist(), np.atleast_1d(c).tolist(),
                    np.atleast_1d(d_ic).astype(float).tolist(), strict=True))
    if method == "ols" and prev.Linv is None:
        x, bread, shift = prev.x, prev.bread, prev.eiv_shift
        J = jacobian_blocks(robot, rest.q) if J is None else J
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
                from analysis.identification.corrections.wrench_eiv import (
                    corrected,
                    wrench_eiv_matrix,
                )

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
        return fit_exact(robot, rest, joints, noise, start=prev.x, J=J)
    return fit(robot, rest, joints, noise, method, J=J)



#: residual tables of more rows than this are held in memory only for the tests with the
#: largest |studentized| residuals (:class:`ResidualRows`; results.json lists 1000 rows and
#: the report 200 tests); the whole table is written to residuals.csv block by block
RESIDUAL_ROWS_HELD = 100_000


def residual_table(tests: TestArrays, fit_: Fit, sigma, t: np.ndarray, flags: np.ndarray,
                   threshold: float, weights: np.ndarray | None):
    """(residuals, rows): the residual table and, for a campaign of more than
    :data:`RESIDUAL_ROWS_HELD` rows, the whole table held as arrays (``residuals`` then
    holds the rows of the tests with the largest |studentized| residuals), else None."""
    rows = ResidualRows(tests, fit_.predicted, sigma, t, flags, weights, threshold=threshold)
    if int(tests.measured.sum()) > RESIDUAL_ROWS_HELD:
        return rows.frame(rows.worst_tests(RESIDUALS_LISTED)), rows
    return rows.frame(), None


def outlier_warning(residuals, rows, flags: np.ndarray, tests: TestArrays, threshold: float,
                    outlier_level: float) -> str | None:
    """The warning naming the residuals beyond ``threshold`` (the five largest) and those
    the sequential test set aside, or None when there are none."""
    n_eq = int(tests.measured.sum())
    flagged = residuals[residuals["outlier"]]
    n_flagged = rows.n_beyond() if rows is not None else len(flagged)
    n_set_aside = int((flags & tests.measured).sum())
    if not n_flagged:
        return None
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
    return (f"{n_flagged} outlier residual(s), |studentized| > {threshold:.2f} (Sidak, "
            f"{level(outlier_level)} family-wise over {n_eq} residuals): {where}{more}{rounds}")


def flag_problem_outliers(problem: IdentificationProblem, first: Fit, scale: float,
                          threshold: float, t_first: np.ndarray | None = None,
                          bias_se: np.ndarray | None = None) -> np.ndarray:
    """:func:`flag_outliers` on an identification ``problem``, taken whole (its robot, tests,
    joints, noise, method and Jacobians)."""
    return flag_outliers(problem.robot, problem.tests, problem.joints, problem.noise,
                         problem.options.method, first, scale, threshold, t_first,
                         bias_se=bias_se, J=problem.jacobian)
