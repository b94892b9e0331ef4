"""Recovery of the true joint stiffness from data of the nonlinear equilibrium, no noise.

Tolerances: the linear model (eqs. 16-18) differs from the finite
displacement by the linearisation error, which grows with the load; on these
six zone poses it moves OLS by 1.2e-2 (relative, worst joint) at the paper's
w_eff and by 1.2e-4 at w_eff / 100 (WLS: 3.3e-2 and 3.4e-4; the weights give
the rotations, whose linearisation error is larger, more say). The exact
fit is limited by the Gauss-Newton tolerance (1e-9 relative step).
The wrench of these data is exact, and the noise model says so (``EXACT_WRENCH``):
no errors-in-variables correction (:mod:`analysis.identification.corrections.wrench_eiv`) is made.
"""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.estimate import identify
from analysis.identification.estimators.exact_model import (
    model_displacement,
    solve_deflection_compliance,
)
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics.equilibrium import displacement_screw, solve_deflection

from ._sim import simulate

EXACT_WRENCH = NoiseModel(force_sigma=0.0, moment_sigma=0.0)


@pytest.mark.parametrize("method, tol", [("ols", 3e-4), ("wls", 7e-4), ("exact", 1e-8)])
def test_small_wrench_recovers_within_the_linearisation_error(kr240, zone_poses, w_eff, method,
                                                              tol):
    """The raw linear estimate errs by the linearisation error; the corrected one (the
    result of ols/wls, :mod:`analysis.identification.corrections.linear_bias`) is exact to 1e-9."""
    k = kr240.nominal_stiffness
    res = identify(kr240, simulate(kr240, zone_poses[:6], w_eff / 100, k), method,
                   noise=EXACT_WRENCH, validate=False)
    if method != "exact":  # the error is the model's, not the solver's: it is there
        raw = np.array(res.linear_bias["raw_joint_stiffness_Nm_per_rad"])
        err = np.abs(raw / k - 1)
        assert tol / 10 < err.max() < tol
        tol = 1e-9
    assert np.abs(res.k / k - 1).max() < tol


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_linear_fits_at_the_paper_wrench_are_corrected(kr240, zone_poses, w_eff, method):
    """At w_eff the raw linear fits are off by 1.2e-2 (OLS) and 3.3e-2 (WLS); corrected:
    the truth to 1e-8 (noise-free data, exact wrench)."""
    k = kr240.nominal_stiffness
    res = identify(kr240, simulate(kr240, zone_poses[:6], w_eff, k), method,
                   noise=EXACT_WRENCH, validate=False)
    raw = np.array(res.linear_bias["raw_joint_stiffness_Nm_per_rad"])
    assert 5e-3 < np.abs(raw / k - 1).max() < 5e-2
    assert np.abs(res.k / k - 1).max() < 1e-8


def test_exact_fit_at_the_paper_wrench_is_solver_limited(kr240, zone_poses, w_eff):
    k = kr240.nominal_stiffness
    res = identify(kr240, simulate(kr240, zone_poses[:6], w_eff, k), "exact", noise=EXACT_WRENCH,
                   validate=False)
    assert np.abs(res.k / k - 1).max() < 1e-8
    assert res.iterations <= 6
    # the change against the linear fits is the linearisation bias: 1e-3 .. 5e-2
    change = np.abs(res.change_vs_linear["ols"])
    assert 1e-3 < change.max() < 5e-2
    ols = res.linear["ols"]
    np.testing.assert_allclose(ols * k - 1, res.change_vs_linear["ols"], rtol=1e-9, atol=1e-12)
    # residuals are at the solver's level, far below the tracker noise
    assert np.abs(res.residuals["residual"]).max() < 1e-10


def test_translational_only_first_three_joints(kr240, zone_poses, w_eff):
    """Knapczyk-Ryska / Alici-Shirinzadeh: translations only, wrist rigid."""
    k = kr240.nominal_stiffness.copy()
    k_rigid_wrist = k.copy()
    k_rigid_wrist[3:] = 1e14
    tests = simulate(kr240, zone_poses, w_eff, k_rigid_wrist, rotations=False)
    res = identify(kr240, tests, "exact", noise=EXACT_WRENCH, validate=False)
    assert res.joints == (0, 1, 2)
    assert np.abs(res.k[:3] / k[:3] - 1).max() < 1e-8
    assert np.all(np.isnan(res.k[3:]))
    assert res.to_dict()["joint_stiffness_Nm_per_rad"][3:] == [None, None, None]
    assert set(res.residuals["component"]) == {"dx", "dy", "dz"}
    assert any("wrist joints 4-6 taken as rigid" in w for w in res.warnings)
    # with a compliant wrist the variant is biased (the wrist's compliance is absorbed)
    biased = identify(kr240, simulate(kr240, zone_poses, w_eff, k, rotations=False), "exact",
                      validate=False)
    assert np.abs(biased.k[:3] / k[:3] - 1).max() > 0.01


def test_joint_subset_others_rigid(kr240, zone_poses, w_eff):
    k = kr240.nominal_stiffness.copy()
    truth = k.copy()
    truth[5] = 1e14
    res = identify(kr240, simulate(kr240, zone_poses[:6], w_eff, truth), "exact",
                   joints=(0, 1, 2, 3, 4), noise=EXACT_WRENCH, validate=False)
    assert np.abs(res.k[:5] / k[:5] - 1).max() < 1e-8
    assert np.isnan(res.k[5]) and res.x[5] == 0.0
    assert res.to_dict()["ci95_Nm_per_rad"][5] is None


def test_compliance_form_matches_the_stiffness_form_equilibrium(kr240, zone_poses, w_eff):
    """Independent check of the exact model against analysis.kinetostatics.equilibrium."""
    k = kr240.nominal_stiffness
    q = zone_poses[:4]
    np.testing.assert_allclose(solve_deflection_compliance(kr240, q, 1 / k, w_eff),
                               solve_deflection(kr240, q, k, w_eff), rtol=0, atol=1e-14)
    f, F = model_displacement(kr240, q, 1 / k, w_eff)
    np.testing.assert_allclose(f, displacement_screw(kr240, q, k, w_eff), rtol=0, atol=1e-14)
    # derivative w.r.t. the compliances against central differences
    x = 1 / k
    for j in range(6):
        h = 1e-4 * x[j]
        e = np.eye(6)[j] * h
        fd = (model_displacement(kr240, q, x + e, w_eff, False)[0]
              - model_displacement(kr240, q, x - e, w_eff, False)[0]) / (2 * h)
        np.testing.assert_allclose(F[..., j], fd, rtol=0, atol=1e-7 * np.abs(F).max())


def test_validation_table_on_clean_data_predicts_to_solver_precision(kr240, zone_poses, w_eff):
    k = kr240.nominal_stiffness
    res = identify(kr240, simulate(kr240, zone_poses[:5], w_eff, k), "exact", noise=EXACT_WRENCH)
    v = res.validation
    assert list(v["held_out_pose"]) == [f"P{i}" for i in range(1, 6)]
    assert v["rms_translation_m"].max() < 1e-10 and v["rms_rotation_rad"].max() < 1e-10


def test_results_dict_has_six_entries_per_joint(kr240, zone_poses, w_eff):
    k = kr240.nominal_stiffness
    res = identify(kr240, simulate(kr240, zone_poses, w_eff, k, rotations=False), "exact",
                   validate=False)
    out = res.to_dict()
    for key in ("joint_stiffness_Nm_per_rad", "ci95_Nm_per_rad", "standard_error_Nm_per_rad"):
        assert len(out[key]) == 6 and out[key][3:] == [None] * 3
    for fit in out["linear_fits_Nm_per_rad"].values():
        assert len(fit) == 6 and fit[3] is None and fit[0] > 0
    assert out["joints_identified"] == [1, 2, 3] and out["n_tests"] == 12
