"""The robustness study's statement of the linear model's bias (`linearisation_bias_relative`,
the note "ols/wls: the mean is biased by ...") is the mean over the noise-free campaigns, so
it matches the Monte-Carlo mean it speaks of. The audit found it was their median: for wls
at w_eff, k2 -0.48 % and k5 -1.00 % against Monte-Carlo means of -0.36 % and -0.70 % (3000
trials, standard error 0.014 % on k2)."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.studies.robustness import robustness_study


@pytest.mark.parametrize("method", ["wls", "ols"])
def test_noise_free_bias_matches_the_monte_carlo_mean(kr240, w_eff, method):
    trials = 4000
    s = robustness_study(kr240, kr240.nominal_stiffness, w_eff, tests=[5], trials=trials,
                         method=method, seed=2)
    s = s.iloc[:3]  # k1..k3: spreads of ~1-3 %, where E[1/x] is k (1 + (std/k)^2) to 1e-5
    rel_std = s["relative_std"].to_numpy()
    mc = (s["mean_Nm_per_rad"] / s["k_true_Nm_per_rad"] - 1).to_numpy() - rel_std ** 2
    nf = s["linearisation_bias_relative"].to_numpy()
    # 4 Monte-Carlo standard errors, plus 3e-4 for the subset of 2000 designs it is taken on
    tol = 4 * rel_std / np.sqrt(trials) + 3e-4
    assert np.all(np.abs(nf - mc) < tol), (nf, mc, tol)
    assert 0.009 < nf[2] < 0.016  # k3, the joint the paper's Fig. 7 shows off by ~1 %
