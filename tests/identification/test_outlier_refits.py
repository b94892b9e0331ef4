"""The outlier loop's refits (downdated OLS, warm-started exact) against fits from scratch."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.checks import outliers
from analysis.identification.checks.outliers import (
    _refit_without,
    _studentized_matrix,
    flag_outliers,
    outlier_threshold,
)
from analysis.identification.estimators.fit_solvers import fit
from analysis.identification.io.measurements import TestArrays
from analysis.identification.linalg.sandwich import sandwich
from analysis.identification.noise import NoiseModel

from ._sim import simulate

NOISE = NoiseModel()


def _without(tests: TestArrays, drop) -> TestArrays:
    keep = tests.measured.copy()
    for i, c in drop:
        keep[i, c] = False
    return TestArrays(tests.pose, tests.q, tests.w, np.where(keep, tests.d, np.nan), keep,
                      tests.line)


@pytest.fixture(scope="module")
def glitched(kr240, zone_poses, w_eff):
    """12 poses, seeded noise, three gross errors (0.8-1 mm) on translation components."""
    tests = simulate(kr240, zone_poses, w_eff, kr240.nominal_stiffness, NOISE, seed=5)
    for (i, c), e in zip([(4, 1), (7, 0), (10, 2)], [1e-3, -8e-4, 1e-3], strict=True):
        tests.d[i, c] += e
    return tests


@pytest.mark.parametrize("method", ["ols", "exact"])
def test_refit_without_equals_fit_from_scratch(kr240, glitched, method):
    joints = tuple(range(6))
    first = fit(kr240, glitched, joints, NOISE, method)
    A0 = first.A.copy()
    drop = [(4, 1), (7, 0)]
    prev, tests = first, glitched
    for n, (i, c) in enumerate(drop):
        rest = _without(glitched, drop[:n + 1])
        prev = _refit_without(kr240, rest, joints, NOISE, method, prev, i, c,
                              float(glitched.d[i, c]))
        tests = rest
    ref = fit(kr240, tests, joints, NOISE, method)
    tol = 1e-9 if method == "ols" else 1e-6  # exact: Gauss-Newton stopping tolerance
    np.testing.assert_allclose(prev.x, ref.x, rtol=tol)
    np.testing.assert_allclose(prev.bread, ref.bread, rtol=1e-6 if method == "exact" else 1e-8)
    # a downdated OLS fit keeps the removed rows in A (their cov rows are zero): compare
    # the design and the prediction on the components kept
    kept = tests.measured
    np.testing.assert_allclose(prev.predicted[kept], ref.predicted[kept], rtol=tol, atol=1e-12)
    np.testing.assert_allclose(prev.A[kept], ref.A[kept], rtol=1e-6, atol=1e-15)
    np.testing.assert_allclose(prev.cov, ref.cov, rtol=1e-6, atol=1e-30)
    np.testing.assert_allclose(sandwich(prev.A, prev.cov, prev.bread, prev.Linv),
                               sandwich(ref.A, ref.cov, ref.bread, ref.Linv), rtol=1e-6)
    t, t_ref = (_studentized_matrix(tests, f, 1.0) for f in (prev, ref))
    np.testing.assert_allclose(t, t_ref, rtol=1e-5, atol=1e-6)  # |t| ~ 1
    # the first fit's arrays are not edited by the downdates
    np.testing.assert_array_equal(first.A, A0)


@pytest.mark.parametrize("method", ["ols", "exact"])
def test_flag_outliers_finds_the_three_glitches(kr240, glitched, method, monkeypatch):
    joints = tuple(range(6))
    first = fit(kr240, glitched, joints, NOISE, method)
    thr = outlier_threshold(int(glitched.measured.sum()))
    flags = flag_outliers(kr240, glitched, joints, NOISE, method, first, 1.0, thr)
    assert {tuple(map(int, ij)) for ij in np.argwhere(flags)} == {(4, 1), (7, 0), (10, 2)}
    # the same flags with every refit from scratch
    monkeypatch.setattr(outliers, "_refit_without", lambda robot, rest, joints, noise, method,
                        *_, **__: fit(robot, rest, joints, noise, method))
    ref = flag_outliers(kr240, glitched, joints, NOISE, method, first, 1.0, thr)
    np.testing.assert_array_equal(flags, ref)


@pytest.mark.parametrize("method", ["ols", "exact"])
def test_outliers_set_aside_at_once_in_large_campaigns(kr240, glitched, method, monkeypatch):
    """The large-campaign rule (every residual beyond the threshold per round, one refit)
    keeps to one at a time where residuals are influential, and its one refit without
    several rows equals a fit from scratch."""
    joints = tuple(range(6))
    first = fit(kr240, glitched, joints, NOISE, method)
    thr = outlier_threshold(int(glitched.measured.sum()))
    one = flag_outliers(kr240, glitched, joints, NOISE, method, first, 1.0, thr)
    calls = []
    real = outliers._refit_without
    monkeypatch.setattr(outliers, "_refit_without",
                        lambda *a, **k: calls.append(np.size(a[6])) or real(*a, **k))
    monkeypatch.setattr(outliers, "OUTLIERS_AT_ONCE_ABOVE", 0)
    many = flag_outliers(kr240, glitched, joints, NOISE, method, first, 1.0, thr)
    np.testing.assert_array_equal(many, one)
    # 12 tests: each residual's leverage is ~p / n = 0.08, and the glitches mask each
    # other (exact: eight residuals beyond the threshold in the first fit): one at a time
    assert calls == [1, 1, 1]
    # without the leverage guard all those beyond would go in the first round
    calls.clear()
    monkeypatch.setattr(outliers, "AT_ONCE_MAX_LEVERAGE", np.inf)
    blind = flag_outliers(kr240, glitched, joints, NOISE, method, first, 1.0, thr)
    beyond = int(np.sum(np.abs(np.nan_to_num(_studentized_matrix(glitched, first, 1.0))) > thr))
    assert calls[0] == beyond >= 3 and (blind >= one).all()
    drop = [(4, 1), (7, 0), (10, 2)]
    i, c = (np.array(v) for v in zip(*drop, strict=True))
    rest = _without(glitched, drop)
    together = real(kr240, rest, joints, NOISE, method, first, i, c, glitched.d[i, c])
    ref = fit(kr240, rest, joints, NOISE, method)
    np.testing.assert_allclose(together.x, ref.x, rtol=1e-9 if method == "ols" else 1e-6)
