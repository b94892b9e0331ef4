"""Tests whose reference reading was under a preload (issue 31): the import columns
fx_ref_N..mz_ref_Nm, the linear model in w - w_ref, the exact model refused."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.errors import InputError
from analysis.identification.estimate import identify
from analysis.identification.io.columns import CSV_COLUMNS, REF_W_COLS
from analysis.identification.io.csv_reader import read_test_arrays
from analysis.identification.noise import NoiseModel
from analysis.kinetostatics import realistic as R
from analysis.model.robots import load_robot

K = np.array([1409800.0, 400760.0, 935280.0, 360000.0, 370000.0, 380000.0])


@pytest.fixture(scope="module")
def campaign():
    """12 poses x 2 loads on the KR240-2 (clean joint springs), each reference reading
    under 30 % of its load: the true displacement loaded minus preloaded, exact model."""
    robot = load_robot("kr240-2")
    rng = np.random.default_rng(11)
    lo, hi = np.deg2rad([-60, 10, -200, -90, -90, -90]), np.deg2rad([60, 110, -175, 90, 90, 90])
    q = np.repeat(rng.uniform(lo, hi, (12, 6)), 2, axis=0)
    w = np.tile([[0, 2200, 2200, 200, 200, 0], [2200, 0, -2200, -200, 200, 0]], (12, 1))
    w = w.astype(float)
    w_ref = 0.3 * w
    d = R.displacement(robot, R.RealisticLab(), K, q, w_ref, w)
    d = d + rng.normal(0, 1e-6, d.shape)  # 1 um, 1 urad
    return robot, q, w, w_ref, d


def _csv(path, q, w, d, w_ref=None, blank_rows=()):
    frame = pd.DataFrame({"pose": np.arange(len(q)) // 2 + 1})
    for j in range(6):
        frame[f"q{j + 1}_deg"] = np.rad2deg(q[:, j])
    for j, c in enumerate(CSV_COLUMNS[7:13]):
        frame[c] = w[:, j]
    for j, c in enumerate(CSV_COLUMNS[13:19]):
        frame[c] = d[:, j] * 1e3
    if w_ref is not None:
        for j, c in enumerate(REF_W_COLS):
            frame[c] = [("" if i in blank_rows else repr(float(v)))
                        for i, v in enumerate(w_ref[:, j])]
    frame.to_csv(path, index=False)
    return path


NOISE = NoiseModel().with_overrides(translation_sigma_override=1e-6,
                                    rotation_sigma_override=1e-6)


def test_preloaded_tests_fit_the_two_equilibria(campaign, tmp_path):
    """The reader keeps the loaded wrench's difference from the reference one; the exact
    model solves both equilibria and the linear ones fit the difference (their
    linearisation-bias correction uses the exact model with the reference): k within
    0.5 % of the truth (1 um noise), where the loaded wrench alone is 30 % off (1 / 0.7)."""
    robot, q, w, w_ref, d = campaign
    tests = read_test_arrays(_csv(tmp_path / "a.csv", q, w, d, w_ref))
    assert np.array_equal(tests.w_ref, w_ref)
    assert np.allclose(tests.w, w - w_ref, rtol=0, atol=1e-9)
    for method in ("exact", "wls"):
        fit = identify(robot, tests, method=method, noise=NOISE, validate=False)
        assert np.max(np.abs(fit.k / K - 1)) < 0.005, method
        assert any("preload" in text for text in fit.warnings)
    ignored = identify(robot, read_test_arrays(_csv(tmp_path / "c.csv", q, w, d)),
                       method="exact", noise=NOISE, validate=False)
    assert np.min(np.abs(ignored.k / K - 1)) > 0.25


def test_exact_model_between_equilibria_against_the_realistic_lab(campaign):
    """model_displacement_state with w_ref = the displacement between the two equilibria
    of analysis.kinetostatics.realistic (independent Newton), and its derivative in x =
    central differences."""
    from analysis.identification.estimators.exact_model import model_displacement_state

    robot, q, w, w_ref, _ = campaign
    x = 1.0 / K
    f, D, ok, _ = model_displacement_state(robot, q, x, w - w_ref, True, w_ref=w_ref)
    assert ok.all()
    truth = R.displacement(robot, R.RealisticLab(), K, q, w_ref, w)
    assert np.max(np.abs(f - truth)) < 1e-12
    h = 1e-12
    fd = np.stack([(model_displacement_state(robot, q, x + h * e, w - w_ref, False,
                                             w_ref=w_ref)[0]
                    - model_displacement_state(robot, q, x - h * e, w - w_ref, False,
                                               w_ref=w_ref)[0]) / (2 * h)
                   for e in np.eye(6)], axis=-1)
    assert np.max(np.abs(D - fd)) < 1e-5 * np.max(np.abs(D))


def test_empty_reference_is_unloaded_and_partial_is_refused(campaign, tmp_path):
    robot, q, w, w_ref, d = campaign
    rows = range(len(q))
    empty = read_test_arrays(_csv(tmp_path / "e.csv", q, w, d, w_ref, blank_rows=rows))
    assert empty.w_ref is None
    frame = pd.read_csv(_csv(tmp_path / "p.csv", q, w, d, w_ref), dtype=str,
                        keep_default_na=False)
    frame.loc[3, "fy_ref_N"] = ""
    frame.to_csv(tmp_path / "p.csv", index=False)
    with pytest.raises(InputError, match="line 5: reference wrench partly empty"):
        read_test_arrays(tmp_path / "p.csv")
    frame.drop(columns=["mz_ref_Nm"]).to_csv(tmp_path / "m.csv", index=False)
    with pytest.raises(InputError, match="mz_ref_Nm missing"):
        read_test_arrays(tmp_path / "m.csv")
