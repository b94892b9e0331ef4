"""The drift statistics as numbers: Holm's adjustment, the one-sided test, the EWMA chart's
variance with correlated changes, the comparability rules (no database here)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import norm

from campaign.ledger.drift import (
    Campaign,
    comparable_reason,
    ewma,
    ewma_chart,
    holm,
    log_variance,
    one_sided_tests,
)

K = np.array([1.4e6, 4.0e5, 9.3e5, 3.6e5, 3.7e5, 3.8e5])


def campaign(k, rel_se=0.002, rid="c", **kw) -> Campaign:
    k = np.asarray(k, float)
    return Campaign(rid, "2026-01-01", k, np.full(6, rel_se**2),
                    kw.get("estimator", "exact"), kw.get("joints", (1, 2, 3, 4, 5, 6)),
                    kw.get("model_class", "m"), kw.get("accepted", False))


def test_holm_by_hand():
    # sorted 0.005 x 4 = 0.02, 0.01 x 3 = 0.03, 0.03 x 2 = 0.06, 0.04 x 1 -> max(0.06, 0.04)
    assert holm(np.array([0.01, 0.04, 0.03, 0.005])) == pytest.approx([0.03, 0.06, 0.06, 0.02])


def test_log_variance_is_the_delta_method_on_the_compliance():
    k = np.array([2.0e5, 4.0e5, np.nan, np.nan, np.nan, np.nan])
    cov_x = [[(0.01 / 2e5) ** 2, 0.0], [0.0, (0.03 / 4e5) ** 2]]  # 1 % and 3 % of x
    v = log_variance(k, cov_x, (1, 2))
    assert v[:2] == pytest.approx([1e-4, 9e-4])
    assert np.isnan(v[2:]).all()


def test_one_sided_test_by_hand():
    ref = campaign(K, 0.003, "r")
    k = K.copy()
    k[1] *= 0.93
    tests = one_sided_tests(campaign(k, 0.004, "c"), ref, 0.05, 0.05)
    t2 = tests[1]
    s = math.hypot(0.003, 0.004)  # 0.005
    z = (math.log(0.93) - math.log(0.95)) / s
    assert t2.se_log == pytest.approx(s)
    assert t2.z == pytest.approx(z)
    assert t2.p == pytest.approx(norm.cdf(z))
    # joint 2 has the smallest p: Holm's first step, level alpha / 6
    assert t2.p_holm == pytest.approx(6 * norm.cdf(z))
    assert t2.bound == pytest.approx(math.expm1(math.log(0.93) + norm.isf(0.05 / 6) * s))
    assert t2.alarm and not any(t.alarm for t in tests if t.joint != 2)


def test_the_boundary_change_is_rejected_at_the_stated_rate():
    """A joint whose true change is exactly -min_change: its unadjusted one-sided test
    rejects in alpha of the campaigns (Monte Carlo, 40,000 pairs, +-4.4 sigma)."""
    rng = np.random.default_rng(3)
    n, rel, m, alpha = 40_000, 0.004, 0.05, 0.05
    ref_k = K * np.exp(rng.normal(0, rel, (n, 6)))
    cur_k = K * np.exp(rng.normal(0, rel, (n, 6)))
    cur_k[:, 1] *= 1 - m
    p = np.array([one_sided_tests(campaign(c, rel), campaign(r, rel), m, alpha)[1].p
                  for r, c in zip(ref_k[:4000], cur_k[:4000], strict=True)])
    # the closed form of the same p-value on all 40,000 pairs
    d = np.log(cur_k[:, 1] / ref_k[:, 1])
    p_all = norm.cdf((d - math.log1p(-m)) / (rel * math.sqrt(2)))
    assert p == pytest.approx(p_all[:4000], rel=1e-9)
    rate = float(np.mean(p_all <= alpha))
    assert abs(rate - alpha) < 4.4 * math.sqrt(alpha * (1 - alpha) / n)


def test_ewma_sd_independent_case_is_the_nist_formula():
    lam = 0.2
    e, sd = ewma(np.zeros(8), np.eye(8), lam)
    i = np.arange(1, 9)
    assert sd == pytest.approx(np.sqrt(lam / (2 - lam) * (1 - (1 - lam) ** (2 * i))))


def test_ewma_sd_with_a_shared_reference_matches_monte_carlo():
    """Changes against one reference are correlated; the chart's sd of E_n is w^T C w."""
    rng = np.random.default_rng(5)
    n_camp, trials, v_ref, v = 6, 200_000, 1.0, 1.0
    ref = rng.normal(0, math.sqrt(v_ref), trials)
    cur = rng.normal(0, math.sqrt(v), (trials, n_camp))
    z = (cur - ref[:, None]) / math.sqrt(v + v_ref)
    e = np.zeros(trials)
    for i in range(n_camp):
        e = 0.2 * z[:, i] + 0.8 * e
    rho = np.full((n_camp, n_camp), v_ref / (v + v_ref))
    np.fill_diagonal(rho, 1.0)
    _, sd = ewma(np.zeros(n_camp), rho)
    assert float(e.std()) == pytest.approx(sd[-1], rel=0.01)
    _, sd_indep = ewma(np.zeros(n_camp), np.eye(n_camp))
    assert sd[-1] > 1.5 * sd_indep[-1]  # the independent formula would be far too narrow


def test_ewma_chart_flags_a_slow_drift_the_last_test_alone_misses():
    """Joint 3 loses 1.2 % per campaign: after six campaigns the chart at m = 0 is below
    its limit while no campaign alone is 5 sigma away."""
    ref = campaign(K, 0.004, "r")
    series = []
    for i in range(1, 7):
        k = K.copy()
        k[2] *= (1 - 0.012) ** i
        series.append(campaign(k, 0.004, f"c{i}"))
    chart = ewma_chart(series, ref, 3, 0.0)
    assert chart["alarm"]
    assert chart["ewma"][-1] < chart["lower_limit"][-1] < 0
    flat = ewma_chart(series, ref, 1, 0.0)
    assert not flat["alarm"] and flat["ewma"] == [0.0] * 6


def test_comparability_reasons():
    ref = campaign(K)
    assert comparable_reason(campaign(K), ref) is None
    assert "estimator" in comparable_reason(campaign(K, estimator="ols"), ref)
    assert "joints" in comparable_reason(campaign(K, joints=(1, 2, 3)), ref)
    assert "model class" in comparable_reason(campaign(K, model_class="n"), ref)
    assert "refusal" in comparable_reason(campaign(K, accepted=True), ref)
