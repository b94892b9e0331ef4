"""Conventions every command shares: --version, choices in --help, renamed options with
hidden aliases, --json in the key style of results.json, no silent overwrite, and the
small pure helpers behind the report's numbers and maps."""

from __future__ import annotations

import importlib.metadata
import json
import re

import numpy as np
import pytest

from campaign.cli import main


def run(args, capsys):
    code = main(args)
    out, err = capsys.readouterr()
    return code, out, err


def _plain(text: str) -> str:
    return re.sub(r"\x1b\[[0-9;]*m", "", text)


def test_version(capsys):
    code, out, _ = run(["--version"], capsys)
    assert code == 0
    assert out.strip().endswith(importlib.metadata.version("robot-stiffness-campaign"))


@pytest.mark.parametrize("command, listed", [
    ("analyze", ["ols|wls|exact", "model|residual"]),
    # plan lists its five strategies in the help text (as one word they fold at 80 columns)
    ("plan", ["worst-joint (default)", "weighted:", "d-optimal", "e-optimal", "zones-random"]),
    ("robustness", ["ols|wls|exact", "reflectors|probe"]),
    ("maps", ["parquet|csv"]),
    # --program lists its choices in words (as one word they fold at 80 columns)
    ("compensate", ["base|tool", "auto (default: by robot), krl (KUKA), urscript (UR), "
                    "rapid (ABB), fanuc-ls (FANUC), none"]),
    ("place", ["max|rms|compliance", "auto (default: by robot), krl (KUKA), urscript (UR), "
               "rapid (ABB), fanuc-ls (FANUC), none"]),
])
def test_help_lists_the_choices(capsys, monkeypatch, command, listed):
    monkeypatch.setenv("COLUMNS", "250")  # one option per line in rich's help box
    code, out, _ = run([command, "--help"], capsys)
    assert code == 0
    text = _plain(out)
    for choices in listed:
        assert choices in text


@pytest.mark.parametrize("command", ["analyze", "robustness"])
def test_unit_options_follow_one_scheme_old_names_hidden(capsys, monkeypatch, command):
    monkeypatch.setenv("COLUMNS", "250")
    text = _plain(run([command, "--help"], capsys)[1])
    for new in ("--translation-sigma-um", "--rotation-sigma-urad", "--force-sigma-N",
                "--moment-sigma-Nm"):
        assert new in text
    assert "--sigma-translation-um" not in text and "--sigma-rotation-urad" not in text


def test_old_and_new_sigma_names_give_the_same_study(capsys):
    base = ["robustness", "--robot", "kr240-2", "--tests", "5", "--trials", "20", "--json",
            "--pool-size", "200"]
    code, new, _ = run([*base, "--translation-sigma-um", "50"], capsys)
    assert code == 0
    code, old, _ = run([*base, "--sigma-translation-um", "50"], capsys)
    assert code == 0
    a, b = json.loads(new), json.loads(old)
    assert a["noise"]["translation_sigma_um"] == pytest.approx(50.0)
    assert a["results"] == b["results"]
    code, _, err = run([*base, "--translation-sigma-um", "50", "--sigma-translation-um", "40"],
                       capsys)
    assert code == 2 and "given twice" in err


def test_robots_json_and_80_columns(capsys):
    code, out, _ = run(["robots", "kr240-2", "--json"], capsys)
    assert code == 0
    r = json.loads(out)
    np.testing.assert_allclose(r["nominal_stiffness_Nm_per_rad"],
                               [1409800, 400760, 935280, 360000, 370000, 380000])
    assert "Table 2" in r["sources"]["stiffness"]
    assert len(r["lower_rad"]) == 6 and r["zones"][0]["name"] == "zone 1"
    code, out, _ = run(["robots", "kr240-2"], capsys)
    assert code == 0
    assert max(len(line) for line in out.splitlines()) <= 80
    code, out, _ = run(["robots", "--json"], capsys)
    assert {"kr240-2", "ur10e"} <= {r["key"] for r in json.loads(out)["robots"]}


def test_maps_json_and_no_silent_overwrite(tmp_path, capsys):
    out = tmp_path / "maps"
    args = ["maps", "--robot", "kr240-2", "--out", str(out), "--step", "10", "--format", "csv",
            "--json"]
    code, text, _ = run(args, capsys)
    assert code == 0
    summary = json.loads(text)
    assert summary == {**json.loads((out / "map_summary.json").read_text()),
                       "files": summary["files"]}
    assert str(out / "map_joint_space.csv") in summary["files"]
    code, _, err = run(args, capsys)
    assert code == 2 and "not empty" in err and "--force" in err
    code, _, _ = run([*args, "--force"], capsys)
    assert code == 0


def test_plan_json_and_no_silent_overwrite(tmp_path, capsys):
    out = tmp_path / "plan"
    args = ["plan", "--protocol", "protocols/kr240-2.toml", "--out", str(out), "--candidates",
            "500", "--no-figure", "--json"]
    code, text, _ = run(args, capsys)
    assert code == 0
    summary = json.loads(text)
    assert summary["tests"] == 5 and summary["plan_file"].endswith("plan.csv")
    code, _, err = run(args, capsys)
    assert code == 2 and "--force" in err
    assert run([*args, "--force"], capsys)[0] == 0


def test_robustness_lists_its_files_and_explains_the_k3_bias(tmp_path, capsys):
    code, out, err = run(["robustness", "--robot", "kr240-2", "--tests", "10,20", "--trials",
                          "200", "--out", str(tmp_path), "--method", "ols"], capsys)
    assert code == 0
    text = " ".join(_plain(out).split())
    for name in ("robustness.csv", "robustness.png", "robustness.json"):
        assert f"wrote {tmp_path / name}" in text
    # ols on the linear model, data from the nonlinear equilibrium: k3 ~ +1.1 %
    note = re.search(r"k3: the mean is \+(\d\.\d\d) to \+(\d\.\d\d) %", text)
    assert note and 0.8 < float(note.group(1)) < 1.5
    assert "1/x transformation explains about +0.0" in text and "--method exact" in text
    saved = json.loads((tmp_path / "robustness.json").read_text())
    assert any(n.startswith("k3:") for n in saved["notes"])
    # it says which method, that ols is the raw linear fit, and how biased its mean is
    assert "method: ols" in text and "the default is exact" in text
    lin = re.search(r"biased by the linearisation.*?k3 \+(\d\.\d\d) %", text)
    assert lin and 0.8 < float(lin.group(1)) < 1.5
    assert saved["method_note"].startswith("method: ols")


def test_robustness_defaults_to_the_method_of_analyze(capsys):
    code, out, _ = run(["robustness", "--robot", "kr240-2", "--tests", "5", "--trials", "20",
                        "--json"], capsys)
    assert code == 0
    saved = json.loads(out)
    assert saved["method"] == "exact" and "the default, as in campaign analyze" in \
        saved["method_note"]
    assert not any("linearisation" in n for n in saved["notes"])


def test_clean_numbers():
    from analysis.report.formatting import clean, eng, fixed, percent, sig

    assert list(clean([1.6e6, -4.7e-11, 3.0])) == [1.6e6, 0.0, 3.0]
    assert eng(-0.0) == "0" and eng(1606.3) == "1606" and eng(-742.61) == "-742.6"
    assert eng(0.91999) == "0.9200" and eng(1.23456e7) == "1.235e7"
    assert fixed(-0.00001, 4) == "0.0000" and fixed(-0.5, 1) == "-0.5"
    assert percent(-1e-6) == "0.00" and percent(0.0123) == "+1.23"
    assert sig(-0.0) == "0"


def test_load_cases_round_to_the_noise():
    from analysis.report.quantities import load_cases

    w = np.array([[2200.3, 0.19, 2199.7, 200.01, 199.98, 0.01],
                  [2199.6, -0.3, 2200.2, 200.0, 200.02, -0.02],
                  [0, 2200, 2200, 200, 200, 0.0]])
    cases = load_cases(w, 0.5, 0.05)
    assert [n for _, n in cases] == [2, 1]
    np.testing.assert_allclose(cases[0][0], [2199.9, 0, 2199.9, 200.0, 200.0, 0])
    assert cases[0][0][1] == 0.0  # 0.19 N and -0.3 N of noise are not a load


def test_map_fixed_joints_one_rule():
    from analysis.kinetostatics.map_fixed import map_fixed_joints

    q = np.radians([[0, 10, 20, -80, 90, 10], [0, 30, 40, -100, 80, 30],
                    [0, 50, 60, -90, 70, 20]])
    m = map_fixed_joints(6, {"q1": 5}, q)
    np.testing.assert_allclose(np.degrees(m.q)[[0, 3, 4, 5]], [5, -90, 80, 20])
    assert m.from_protocol == (0,) and m.from_poses == (3, 4, 5)
    assert m.values_text() == "\u03b81 = 5, \u03b84 = -90, \u03b85 = 80, \u03b86 = 20 deg"
    assert "\u03b84, \u03b85, \u03b86 the median of the tested poses" in m.rule_text()


def test_robustness_says_its_default_wrench(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    code, out, err = run(["robustness", "--robot", "kr240-2", "--tests", "5", "--trials",
                          "10", "--pool-size", "100", "--json"], capsys)
    assert code == 0
    data = json.loads(out)
    assert data["wrench_N_Nm"] == [0, 2200, 2200, 200, 200, 0]
    assert data["wrench_source"].startswith("default: the paper's w_eff (eq. 22)")
    flat = " ".join(_plain(err).split())
    assert "wrench w = [0, 2200, 2200] N, [200, 200, 0] N m at P, base frame (default: the " \
           "paper's w_eff (eq. 22); --wrench to choose another)" in flat
