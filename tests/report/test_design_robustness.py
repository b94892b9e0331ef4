"""The robustness curve of a campaign's design against the campaign's own standard errors."""

from __future__ import annotations

import numpy as np
import pytest
from report_runs import REPEATS, SIGMA, TRUE_K

from analysis.errors import InputError
from analysis.identification.estimate import analyze_table
from analysis.identification.io.csv_reader import read_csv
from analysis.identification.io.measurements import to_arrays
from analysis.identification.noise import NoiseModel
from analysis.model.robots import load_robot
from analysis.report.design_robustness import design_robustness, design_tests, draw_tests


def test_draws_repeat_the_design_then_add_distinct_tests():
    rng = np.random.default_rng(0)
    idx = draw_tests(5, 13, 50, rng)
    assert idx.shape == (50, 13)
    counts = np.stack([np.bincount(row, minlength=5) for row in idx])
    assert np.all(counts >= 2) and np.all(counts <= 3) and np.all(counts.sum(1) == 13)
    small = draw_tests(5, 3, 50, rng)
    assert all(len(set(r)) == 3 for r in small.tolist())


def test_spread_at_the_campaign_size_meets_its_standard_errors(tmp_path, rows):
    from report_runs import write_csv

    robot = load_robot("kr240-2")
    noise = NoiseModel(translation_sigma_override=SIGMA[0], rotation_sigma_override=SIGMA[3],
                       force_sigma=0.5, moment_sigma=0.05)
    table = read_csv(write_csv(tmp_path / "t.csv", rows))
    tests = to_arrays(table)
    q, w = design_tests(tests.q, tests.w)
    assert len(q) == 5  # 15 rows = 5 poses x 3 repeats
    result = analyze_table(table, robot, method="exact", noise=noise, validate=False)
    n = 5 * REPEATS
    curve = design_robustness(robot, q, w, TRUE_K, noise, range(6), tests=(3, n, 4 * n),
                              trials=400, seed=1)
    at_n = curve[curve["n_tests"] == n].sort_values("joint")["relative_std"].to_numpy()
    np.testing.assert_allclose(at_n, result.se_k / result.k, rtol=0.2)
    # four times the tests: half the spread (within Monte-Carlo error)
    at_4n = curve[curve["n_tests"] == 4 * n].sort_values("joint")["relative_std"].to_numpy()
    np.testing.assert_allclose(at_4n / at_n, 0.5, rtol=0.2)
    assert np.all(np.abs(curve["relative_bias"]) < 0.05)
    # a well-conditioned design: the robust spread (IQR / 1.349) agrees with the std, and
    # the quartiles bracket the median
    big = curve[curve["n_tests"] >= n]
    assert big["identifiable"].all()
    np.testing.assert_allclose(big["robust_sigma"], big["relative_std"], rtol=0.25)
    assert np.all(big["relative_q25"] < big["relative_bias"])
    assert np.all(big["relative_bias"] < big["relative_q75"])


def test_a_design_lost_in_the_noise_is_marked_not_identifiable():
    """A load a thousand times too small leaves deflections far below the noise: every n
    is 'not identifiable' (shown as such in the report, not as a number)."""
    robot = load_robot("kr240-2")
    noise = NoiseModel(translation_sigma_override=SIGMA[0], rotation_sigma_override=SIGMA[3],
                       force_sigma=0.5, moment_sigma=0.05)
    q = np.radians([[0, 40, -200, 45, 45, 45], [20, 80, -220, 30, 60, -30]])
    w = np.array([[0, 2.2, 2.2, 0.2, 0.2, 0.0], [2.2, 0, 2.2, 0.2, -0.2, 0.0]])
    curve = design_robustness(robot, q, w, TRUE_K, noise, range(6), tests=(3, 10), trials=40)
    assert not curve["identifiable"].any()


def test_too_few_trials_is_refused(rows):
    with pytest.raises(InputError, match="at least 10 trials"):
        design_robustness(load_robot("kr240-2"), np.zeros((1, 6)), np.ones((1, 6)), TRUE_K,
                          NoiseModel(), range(6), trials=5)
