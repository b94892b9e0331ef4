"""``campaign robustness`` and ``campaign analyze --measurements``: files and exit codes."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from analysis.identification.io.columns import CSV_COLUMNS
from analysis.identification.io.measurements import table_from_arrays, to_csv_frame
from analysis.identification.noise import NoiseModel
from campaign.cli import main

from ._sim import simulate


def test_robustness_writes_table_plot_and_settings(tmp_path, capsys):
    out = tmp_path / "rob"
    rc = main(["robustness", "--robot", "kr240-2", "--tests", "2,5", "--trials", "60",
               "--pool-size", "60", "--out", str(out)])
    assert rc == 0
    table = pd.read_csv(out / "robustness.csv")
    assert sorted(table["n_tests"].unique()) == [2, 5]
    assert set(table["joint"]) == set(range(1, 7)) and (table["trials"] == 60).all()
    assert (out / "robustness.png").stat().st_size > 10_000
    settings = json.loads((out / "robustness.json").read_text())
    assert settings["wrench_N_Nm"] == [0.0, 2200.0, 2200.0, 200.0, 200.0, 0.0]
    assert "k6 std/k" in capsys.readouterr().out


def test_robustness_bad_options_exit_2(capsys):
    assert main(["robustness", "--robot", "kr240-2", "--tests", "5..2"]) == 2
    assert "--tests" in capsys.readouterr().err
    assert main(["robustness", "--robot", "kr240-2", "--tests", "3", "--trials", "10",
                 "--rotation-source", "camera"]) == 2
    assert "--rotation-source" in capsys.readouterr().err


def test_analyze_csv_writes_results_json(tmp_path, kr240, zone_poses, w_eff):
    noise = NoiseModel()
    tests = simulate(kr240, zone_poses[:6], w_eff, kr240.nominal_stiffness, noise, seed=9)
    frame = to_csv_frame(table_from_arrays(tests.pose, tests.q, tests.w, tests.d))
    csv = tmp_path / "tests.csv"
    frame[CSV_COLUMNS].to_csv(csv, index=False)
    out = tmp_path / "out"
    rc = main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out", str(out),
               "--no-report"])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    assert res["method"] == "exact" and res["n_tests"] == 6
    assert np.all(np.abs(k / kr240.nominal_stiffness - 1) < 0.3)
    assert len(res["ci95_Nm_per_rad"]) == 6
    assert all(lo < kk < hi for (lo, hi), kk in zip(res["ci95_Nm_per_rad"], k, strict=True))
    assert res["condition_number"] > 1
    assert len(res["residuals"]) == 36
    resid = pd.read_csv(out / "residuals.csv")
    assert list(resid.columns[:4]) == ["test", "line", "pose", "component"]


def test_analyze_csv_bad_cell_exit_2(tmp_path, capsys):
    csv = tmp_path / "bad.csv"
    row = ["P1"] + ["0"] * 6 + ["0", "100", "0", "0", "0", "0"] + ["abc", "0", "0", "", "", ""]
    csv.write_text(",".join(CSV_COLUMNS) + "\n" + ",".join(row) + "\n")
    rc = main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out",
               str(tmp_path / "o"), "--no-report"])
    assert rc == 2
    assert "line 2, column dx_mm: 'abc' is not a number" in capsys.readouterr().err


def test_analyze_noise_overrides_scale_the_intervals(tmp_path, kr240, zone_poses, w_eff):
    """Doubling every sigma on the command line doubles the standard errors (known-sigma
    covariance, exact fit: se is proportional to the noise scale) and leaves the fit
    unchanged except for the wrench errors-in-variables correction, which grows as
    sigma_w^2 relative to the (scale-free) normal matrix: four times the shift."""
    noise = NoiseModel()
    tests = simulate(kr240, zone_poses[:6], w_eff, kr240.nominal_stiffness, noise, seed=4)
    csv = tmp_path / "tests.csv"
    to_csv_frame(table_from_arrays(tests.pose, tests.q, tests.w, tests.d))[CSV_COLUMNS].to_csv(
        csv, index=False)
    base = ["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--no-report"]
    t, r = noise.translation_sigma, noise.rotation_sigma
    f, m = noise.force_sigma, noise.moment_sigma
    opts = ["--translation-sigma-um", f"{t * 1e6:.12g}", "--rotation-sigma-urad",
            f"{r * 1e6:.12g}", "--force-sigma-N", f"{f:.12g}", "--moment-sigma-Nm", f"{m:.12g}"]
    doubled = ["--translation-sigma-um", f"{2 * t * 1e6:.12g}", "--rotation-sigma-urad",
               f"{2 * r * 1e6:.12g}", "--force-sigma-N", f"{2 * f:.12g}",
               "--moment-sigma-Nm", f"{2 * m:.12g}"]
    assert main([*base, "--out", str(tmp_path / "a"), *opts]) == 0
    assert main([*base, "--out", str(tmp_path / "b"), *doubled]) == 0
    a = json.loads((tmp_path / "a" / "results.json").read_text())
    b = json.loads((tmp_path / "b" / "results.json").read_text())
    # k = k_uncorrected / (1 - relative shift)
    # (analysis.identification.corrections.wrench_eiv.shift_summary)
    rel_a = np.array(a["wrench_errors_in_variables"]["relative_shift_of_k"])
    rel_b = np.array(b["wrench_errors_in_variables"]["relative_shift_of_k"])
    np.testing.assert_allclose((1 - rel_b) * b["joint_stiffness_Nm_per_rad"],
                               (1 - rel_a) * np.array(a["joint_stiffness_Nm_per_rad"]),
                               rtol=1e-6)
    assert np.all(np.abs(rel_a) > 1e-6)
    # first order in S: 4x; the second-order term is ~4 |rel_a| relative
    np.testing.assert_allclose(rel_b, 4 * rel_a, rtol=20 * np.max(np.abs(rel_a)))
    # se_k = se_x / x^2 and se_x's bread (N - S)^-1 move with the shift, at its order
    np.testing.assert_allclose(b["standard_error_Nm_per_rad"],
                               2 * np.array(a["standard_error_Nm_per_rad"]),
                               rtol=4 * np.max(np.abs(rel_b)))
    assert main([*base, "--out", str(tmp_path / "c"), "--force-sigma-N", "-1"]) == 2
