"""The sensitivity explorer's job shows no Monte-Carlo k for a joint its tests do not
identify: with every test at one wrist-singular pose the least-squares k of a trial is an
arbitrary number (k4 came out near 37 N m/rad for a true 360 000), so the spread is
missing (None) and every trial is counted rejected, beside the planner's 'not
identifiable'; a design that identifies the joints still gets its numbers."""

from __future__ import annotations

import numpy as np

from campaign.jobs.sensitivity import SensitivityOptions, run_sensitivity


def test_equal_singular_poses_give_no_k():
    q = np.zeros((2, 6))  # KR240-2, q5 = 0: the wrist is singular
    d = run_sensitivity(SensitivityOptions(robot="kr240-2", poses="typed", q=q, trials=50,
                                           n_tests=10)).to_dict()
    assert d["n_tests"] == 10
    for j in d["joints"]:
        assert j["predicted_se_Nm_per_rad"] is None
        assert j["median_Nm_per_rad"] is None and j["std_Nm_per_rad"] is None
        assert j["q25_Nm_per_rad"] is None and j["q75_Nm_per_rad"] is None
        assert j["rejected"] == 50
    assert all(v is None for s in d["sets_Nm_per_rad"] for v in s)


def test_a_design_that_identifies_keeps_its_numbers():
    q = np.radians([[10, 20, 30, 40, 50, 60], [-20, 10, 20, 70, -40, 10],
                    [30, 30, -10, -60, 60, 40]])
    d = run_sensitivity(SensitivityOptions(robot="kr240-2", poses="typed", q=q, trials=200,
                                           n_tests=10)).to_dict()
    for j in d["joints"]:
        k, med, se = j["k_true_Nm_per_rad"], j["median_Nm_per_rad"], j["predicted_se_Nm_per_rad"]
        assert se is not None and 0 < se < 0.2 * k
        assert abs(med - k) < 5 * j["std_Nm_per_rad"]  # the median near the truth
        assert j["rejected"] < 200
