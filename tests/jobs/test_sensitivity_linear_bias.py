"""The sensitivity explorer corrects ols/wls for their linearisation bias, as Analyze does,
and says by how much: with the noise made tiny the corrected medians sit on the true k
while the bias it names is the one an independent least-squares fit of the exact
displacements shows; exact needs no correction and names none."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.estimators.linear_model import design_block
from analysis.kinetostatics.equilibrium import displacement_screw
from analysis.model.kinematics import jacobian
from analysis.model.robots import load_robot
from campaign.jobs.sensitivity import ErrorSources, SensitivityOptions, run_sensitivity

#: three well-spread poses (deg) of the KR240-2, every joint identified
Q_DEG = [[10, 20, 30, 40, 50, 60], [-20, 10, 20, 70, -40, 10], [30, 30, -10, -60, 60, 40]]
#: a tenth of a micrometre, a tenth of a microradian, 1 mN, 0.1 mN m: the spread well
#: under the linearisation bias
TINY = ErrorSources(translation_sigma=1e-7, rotation_sigma=1e-7, force_sigma=1e-3,
                    moment_sigma=1e-4, force_relative=0.0, moment_relative=0.0,
                    encoder_resolution=1e-9)


def _run(method: str, errors=TINY, trials=40):
    return run_sensitivity(SensitivityOptions(
        robot="kr240-2", poses="typed", q=np.radians(Q_DEG), n_tests=6, trials=trials,
        method=method, errors=errors)).to_dict()


def _ols_bias_by_hand(n_tests: int = 6) -> np.ndarray:
    """k of an unweighted least-squares fit of the linear model to the exact displacements
    of the same tests (numpy's lstsq), relative to the true k, less one."""
    from analysis.identification.studies.robustness import W_EFF

    robot = load_robot("kr240-2")
    k = np.asarray(robot.nominal_stiffness, float)
    q = np.radians(np.asarray(Q_DEG, float))[np.arange(n_tests) % 3]
    w = np.broadcast_to(W_EFF, (n_tests, 6))
    d = displacement_screw(robot, q, k, w)
    A = design_block(jacobian(robot, q), w).reshape(6 * n_tests, 6)
    x = np.linalg.lstsq(A, d.reshape(-1), rcond=None)[0]
    return (1.0 / x) / k - 1.0


def test_ols_medians_are_corrected_and_the_bias_named_is_the_fits():
    d = _run("ols")
    by_hand = _ols_bias_by_hand()
    named = np.array([j["linear_bias_relative"] for j in d["joints"]])
    assert named == pytest.approx(by_hand, abs=1e-6)
    assert np.max(np.abs(named)) > 1e-3  # a bias worth correcting at these tests
    for j in d["joints"]:  # the corrected medians: on the truth, far inside the bias
        rel = j["median_Nm_per_rad"] / j["k_true_Nm_per_rad"] - 1
        assert abs(rel) < max(1e-4, 0.05 * abs(j["linear_bias_relative"]))
    # the page's sentence carries each joint's number
    assert d["note"].startswith("ols fits the linearised model")
    for i, b in enumerate(by_hand, start=1):
        assert f"k{i} {100 * b:+.2f} %" in d["note"]


def test_the_corrected_wls_median_agrees_with_the_exact_fit():
    """Same seed, same noisy campaigns: the corrected wls medians and the exact fit's agree
    to a small part of the spread (the default noise)."""
    wls, exact = _run("wls", ErrorSources(), 200), _run("exact", ErrorSources(), 200)
    assert exact["note"] == "" and all(j["linear_bias_relative"] == 0 for j in exact["joints"])
    assert "wls fits the linearised model" in wls["note"]
    for a, b in zip(wls["joints"], exact["joints"], strict=True):
        gap = abs(a["median_Nm_per_rad"] - b["median_Nm_per_rad"])
        # uncorrected, the gap would be about the bias itself (0.4-1.5 % of k here)
        assert gap < 0.1 * abs(a["linear_bias_relative"]) * a["k_true_Nm_per_rad"]
