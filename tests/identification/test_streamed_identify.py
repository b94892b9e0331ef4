"""The streamed (blockwise) identification of large campaigns equals the in-memory one.

A campaign of 1200 tests (80 poses x 15 loads, one 1 mm glitch) is identified twice:
with the default sizes, where it is small enough for the dense paths (one QR of the
stacked system, one block of model evaluations, the whole residual table in memory),
and with the block sizes shrunk so that every large-campaign path runs (whitened
systems by blockwise TSQR, model and Jacobians in blocks of 101 and 97 tests, TSQR
blocks of 50 rows, J and the design made block by block when sliced instead of
held, residual table held as arrays and written to residuals.csv block by
block). Both are backward-stable factorisations of the same systems, so they agree to
rounding: 1e-9 relative here (Gauss-Newton stops at 1e-9 of x; measured ~1e-13).
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from analysis.identification.checks import outliers
from analysis.identification.estimate import identify
from analysis.identification.estimators import linear_model
from analysis.identification.io.measurements import TestArrays
from analysis.identification.io.results_json import write_results
from analysis.identification.linalg import lsq
from analysis.identification.noise import NoiseModel
from analysis.identification.streaming import blocks, per_test
from analysis.identification.studies.robustness import sample_poses
from analysis.identification.validation import downdate

from ._sim import simulate

NOISE = NoiseModel()
PER_POSE = 15


@pytest.fixture(scope="module")
def campaign(kr240, w_eff):
    rng = np.random.default_rng(21)
    poses = sample_poses(kr240, 80, rng, min_inverse_condition=0.3)
    q = np.repeat(poses, PER_POSE, axis=0)
    w = w_eff * rng.uniform(0.3, 0.6, size=(len(q), 1)) * rng.choice([-1.0, 1.0], (len(q), 1))
    sim = simulate(kr240, q, w, kr240.nominal_stiffness, NOISE, seed=4)
    d = sim.d.copy()
    d[37, 1] += 1e-3  # a 1 mm glitch: one outlier to find
    names = np.repeat([f"Z{i + 1}" for i in range(len(poses))], PER_POSE)
    return TestArrays(pose=names, q=sim.q, w=sim.w, d=d, measured=sim.measured, line=sim.line)


def _streamed(monkeypatch):
    monkeypatch.setattr(lsq, "TALL_ROWS", 600)
    monkeypatch.setattr(lsq, "TEST_BLOCK", 97)
    monkeypatch.setattr(lsq, "ROW_BLOCK", 50)
    monkeypatch.setattr(outliers, "RESIDUAL_ROWS_HELD", 100)
    monkeypatch.setattr(blocks, "EVAL_BLOCK", 101)
    # J, the design and the model Jacobian are made when sliced instead of held
    monkeypatch.setattr(per_test, "LAZY_TESTS", 300)
    monkeypatch.setattr(downdate, "FOLD_CHUNK", 7)  # the folds' algebra in chunks


@pytest.mark.parametrize("method", ["ols", "exact"])
def test_streamed_identification_equals_the_in_memory_one(kr240, campaign, method,
                                                          monkeypatch, tmp_path):
    ref = identify(kr240, campaign, method, noise=NOISE)
    write_results(ref, tmp_path / "ref")
    _streamed(monkeypatch)
    from analysis.identification.streaming.per_test import PerTestJacobian

    assert isinstance(linear_model.jacobian_blocks(kr240, campaign.q), PerTestJacobian)
    res = identify(kr240, campaign, method, noise=NOISE)
    write_results(res, tmp_path / "res")
    assert ref.residual_rows is None and res.residual_rows is not None
    # estimate, covariance, goodness of fit, conditioning
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-9)
    np.testing.assert_allclose(res.cov_x, ref.cov_x, rtol=1e-8)
    for name in ("chi2_reduced", "p_value", "condition_number", "condition_number_weighted"):
        assert getattr(res, name) == pytest.approx(getattr(ref, name), rel=1e-8), name
    # a streamed exact fit starts from OLS without the WLS comparison fit
    assert set(res.linear) == ({"ols"} if method == "exact" else set(ref.linear))
    for name in res.linear:
        np.testing.assert_allclose(res.linear[name], ref.linear[name], rtol=1e-9)
    # outliers: the glitch, and the same flags
    flagged = ref.residuals[ref.residuals["outlier"]]
    assert (37, "dy") in set(zip(flagged["test"], flagged["component"], strict=True))
    held = res.residuals.set_index(["test", "component"])
    full = ref.residuals.set_index(["test", "component"])
    assert set(held[held["outlier"]].index) == set(full[full["outlier"]].index)
    # the rows held are those of the worst tests, with the same values
    assert len(held) < len(full) and held.index.isin(full.index).all()
    np.testing.assert_allclose(held["studentized"], full.loc[held.index, "studentized"],
                               rtol=1e-7)
    # residuals.csv holds every row either way
    a, b = (pd.read_csv(tmp_path / d / "residuals.csv") for d in ("ref", "res"))
    assert list(a.columns) == list(b.columns) and len(a) == len(b) == int(
        campaign.measured.sum())
    for col in a.columns:
        if a[col].dtype == float:
            # absolute floor relative to the column's scale: x agrees to ~1e-14, so a
            # studentized residual near 0 moves by ~1e-11 (measured) between the paths
            np.testing.assert_allclose(b[col], a[col], rtol=1e-7,
                                       atol=1e-10 * np.abs(a[col]).max() + 1e-15,
                                       err_msg=col)
        else:
            assert (a[col].astype(str) == b[col].astype(str)).all(), col
    # validation: same folds, same figures (one Gauss-Newton step per fold for exact)
    va, vb = ref.validation, res.validation
    assert list(va["held_out_pose"]) == list(vb["held_out_pose"]) and len(va) == 80
    for col in ("rms_translation_m", "rms_rotation_rad", "rms_normalized",
                "rms_normalized_total", "limit_normalized_total"):
        np.testing.assert_allclose(vb[col], va[col], rtol=1e-8, err_msg=col)
    assert list(va["beyond_limit"]) == list(vb["beyond_limit"])
    assert list(va["note"]) == list(vb["note"])
    # results.json: the same listed rows, histogram and validation summary
    ja, jb = (json.loads((tmp_path / d / "results.json").read_text()) for d in ("ref", "res"))
    assert ja["residual_histogram"] == jb["residual_histogram"]
    assert [(r["test"], r["component"]) for r in ja["residuals"]] == [
        (r["test"], r["component"]) for r in jb["residuals"]]
    assert ja["validation_summary"]["n_poses"] == jb["validation_summary"]["n_poses"] == 80
    assert ja["validation_summary"]["rms_normalized_max"] == pytest.approx(
        jb["validation_summary"]["rms_normalized_max"], rel=1e-8)


def test_validation_beyond_the_listed_poses_is_summarised(kr240, campaign, monkeypatch):
    from analysis.identification.io import results_json as result_module

    res = identify(kr240, campaign, "ols", noise=NOISE)
    monkeypatch.setattr(result_module, "VALIDATION_LISTED", 10)
    out = result_module.validation_summary(res.validation, listed=10)
    listed = pd.DataFrame(out["validation"])
    assert len(listed) == 10 and "10 of 80" in out["validation_listed"]
    worst = res.validation["rms_normalized_total"].nlargest(10)
    np.testing.assert_allclose(listed["rms_normalized_total"], worst.to_numpy())
    summary = out["validation_summary"]
    v = res.validation
    assert summary["rms_normalized_max"] == pytest.approx(v["rms_normalized"].max())
    assert summary["rms_normalized_median"] == pytest.approx(v["rms_normalized"].median())
    pooled = np.sqrt(np.sum(v["n_tests"] * v["rms_translation_m"] ** 2) / v["n_tests"].sum())
    assert summary["rms_translation_m_pooled"] == pytest.approx(pooled, rel=1e-12)
    assert summary["folds_not_fitted"] == 0


@pytest.mark.parametrize("method", ["ols", "exact"])
def test_blockwise_covariances_with_a_held_jacobian(kr240, campaign, method, monkeypatch):
    """Campaigns between one model block and the lazy size: J held, the covariances and
    the residual sigmas made block by block (and for the rows of the residual table)."""
    ref = identify(kr240, campaign, method, noise=NOISE)
    monkeypatch.setattr(blocks, "EVAL_BLOCK", 101)
    res = identify(kr240, campaign, method, noise=NOISE)
    assert not isinstance(linear_model.jacobian_blocks(kr240, campaign.q),
                          per_test.PerTestJacobian)
    np.testing.assert_allclose(res.x, ref.x, rtol=1e-9)
    for col in ("sigma", "studentized", "predicted"):
        np.testing.assert_allclose(res.residuals[col], ref.residuals[col], rtol=1e-7,
                                   atol=1e-10 * np.abs(ref.residuals[col]).max(), err_msg=col)


def test_the_problem_systems_choose_the_statistics_and_both_agree(kr240, campaign,
                                                                  monkeypatch):
    """The statistics are the problem's systems' to choose: a streamed exact fit's come
    from the R of its final pass, and equal those of a pass of their own over the same
    fit (:func:`held_statistics`: the meat summed block by block, the chi-square from the
    residuals) to rounding, 1e-9; a linear fit of the same streamed campaign, which has
    no final pass, gets the pass of its own; a small campaign's systems are held."""
    from analysis.identification.estimators.registry import estimator
    from analysis.identification.problem import IdentificationProblem
    from analysis.identification.statistics import (
        final_pass_statistics,
        fit_statistics,
        held_statistics,
    )
    from analysis.identification.streaming.systems import HeldSystems, StreamedSystems

    assert IdentificationProblem.make(kr240, campaign, noise=NOISE).systems is HeldSystems
    _streamed(monkeypatch)
    problem = IdentificationProblem.make(kr240, campaign, noise=NOISE)
    assert problem.systems is StreamedSystems
    outcome = estimator("exact").fit(problem)
    assert outcome.fit.predicted is None  # deferred to the statistics pass
    stats, done = fit_statistics(problem, outcome)
    again, _ = final_pass_statistics(problem, outcome)
    np.testing.assert_array_equal(stats.cov_x, again.cov_x)  # the same implementation
    assert done.fit.predicted is not None and done.fit.predicted_shifted
    own = held_statistics(problem, done)
    np.testing.assert_allclose(stats.cov_x, own.cov_x, rtol=1e-9)
    np.testing.assert_allclose(stats.var_r, own.var_r, rtol=1e-9, atol=1e-24)
    assert stats.chi2_reduced == pytest.approx(own.chi2_reduced, rel=1e-9)
    assert stats.dof == own.dof == int(campaign.measured.sum()) - 6
    # the singular values of the whitened system: its R either way
    np.testing.assert_allclose(np.linalg.svd(stats.Aw, compute_uv=False),
                               np.linalg.svd(own.Aw, compute_uv=False), rtol=1e-9)
    lin = estimator("ols").fit(problem)
    lin_stats, lin_out = fit_statistics(problem, lin)
    assert lin_out is lin
    np.testing.assert_array_equal(lin_stats.cov_x, held_statistics(problem, lin).cov_x)
