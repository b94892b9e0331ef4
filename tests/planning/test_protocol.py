"""Protocol files: the examples load with the right SI values; bad files name key and line."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import yaml

from analysis.errors import InputError
from campaign.cli import main
from campaign.planning.planner import make_plan
from campaign.protocol import load_protocol

ROOT = Path(__file__).resolve().parents[2]
KR_FILE = ROOT / "protocols" / "kr240-2.toml"
UR_FILE = ROOT / "protocols" / "ur10e.toml"


def _line_of(text: str, needle: str) -> int:
    """1-based line of the first line containing ``needle``."""
    for i, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            return i
    raise AssertionError(f"{needle!r} not in text")


def _variant(tmp_path, old: str, new: str, name: str = "bad.toml") -> tuple[str, str]:
    text = KR_FILE.read_text()
    assert old in text
    text = text.replace(old, new, 1)
    path = tmp_path / name
    path.write_text(text)
    return str(path), text


def test_kr240_example_values_in_si(kr_protocol):
    w = kr_protocol.wrenches()
    # eq. (22) of the paper, first load case
    assert np.array_equal(w[0], [0, 2200, 2200, 200, 200, 0])
    assert w.shape == (4, 6)
    sigma = kr_protocol.measurement_sigma()
    assert sigma[0] == pytest.approx(30e-6 / math.sqrt(3), rel=1e-12)
    assert sigma[3] == pytest.approx(20e-6 / math.sqrt(3), rel=1e-12)
    lab = kr_protocol.lab
    assert lab["true_joint_stiffness"] == (1409800, 400760, 935280, 360000, 370000, 380000)
    assert lab["tracker_noise"] == pytest.approx(30e-6)
    assert lab["tracker_angle_noise"] == pytest.approx(20e-6)
    assert lab["time_scale"] == 50
    assert kr_protocol.instruments["force_torque"].address == "udp://192.168.1.1:49152"


def test_ur10e_example_hanging_mass_is_down(ur_protocol):
    w = ur_protocol.wrenches()
    assert np.allclose(w[0], [0, 0, -98.1, 0, 0, 0])
    assert ur_protocol.instruments["force_torque"].address == "/dev/ttyUSB0?baud=19200"


def test_yaml_protocol_equals_toml(tmp_path, kr_protocol):
    data = tomllib.loads(KR_FILE.read_text())
    path = tmp_path / "kr.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    from_yaml = load_protocol(path)
    assert from_yaml.model_dump() == kr_protocol.model_dump()
    a = make_plan(from_yaml, seed=2, candidates=500).to_frame()
    b = make_plan(kr_protocol, seed=2, candidates=500).to_frame()
    assert a.equals(b)


@pytest.mark.parametrize(
    ("old", "new", "needle", "key", "words"),
    [
        ("max_v_p = 0.02", "max_v_p = 0.02\ncolour = 'red'", "colour", "thresholds.colour",
         "unknown key"),
        ("tests = 5 ", 'tests = "five" ', "tests =", "campaign.tests", "integer"),
        ("mass_kg = 0", "mass_kg = -2", "mass_kg", "tool.mass_kg", "greater than or equal"),
        ("noise = { translation_um = 30, rotation_urad = 20 }",
         "noise = { translation_um = 'x', rotation_urad = 20 }", "translation_um = 'x'",
         "instruments.pose.noise.translation_um", "number"),
        ('method = "cable-pulley"', 'method = "catapult"', "catapult", "load_cases[0].method",
         "cable-pulley"),
        ("fixed_deg = { q1 = 0,", "fixed_deg = { q9 = 0,", "q9", "sampling.fixed_deg",
         "q1..q6"),
    ],
)
def test_schema_errors_name_key_and_line(tmp_path, old, new, needle, key, words):
    path, text = _variant(tmp_path, old, new)
    with pytest.raises(InputError) as err:
        load_protocol(path)
    msg = str(err.value)
    assert f"{path}:{_line_of(text, needle)}: {key}" in msg
    assert words in msg


def test_yaml_unknown_key_names_line(tmp_path):
    data = tomllib.loads(KR_FILE.read_text())
    data["safety"]["max_speed"] = 3
    path = tmp_path / "kr.yaml"
    text = yaml.safe_dump(data, sort_keys=False)
    path.write_text(text)
    with pytest.raises(InputError, match="unknown key") as err:
        load_protocol(path)
    assert f"{path}:{_line_of(text, 'max_speed:')}: safety.max_speed" in str(err.value)


def test_zone_outside_joint_limits(tmp_path):
    # theta3 of the KR240-2 spans [-245, 30] deg in the model convention
    zone = '[[zones]]\nname = "too low"\nranges_deg = { q2 = [0, 110], q3 = [-260, -170] }\n'
    path, text = _variant(tmp_path, "[thresholds]", zone + "\n[thresholds]")
    protocol = load_protocol(path)
    with pytest.raises(InputError) as err:
        make_plan(protocol, candidates=200)
    msg = str(err.value)
    assert f"{path}:{_line_of(text, 'q3 = [-260')}: zones[0].ranges_deg.q3" in msg
    assert "outside the joint limits [-245, 30] deg" in msg


def test_fixed_joint_outside_limits(tmp_path):
    path, text = _variant(tmp_path, "q5 = 45, q6", "q5 = 130, q6")
    with pytest.raises(InputError) as err:
        make_plan(load_protocol(path), candidates=200)
    assert f"{path}:{_line_of(text, 'fixed_deg')}: sampling.fixed_deg.q5" in str(err.value)


@pytest.mark.parametrize(
    ("old", "new", "key"),
    [
        ("min_inv_kappa_F = 0.40", "min_inv_kappa_F = 0.90", "thresholds.min_inv_kappa_F"),
        ("max_v_p = 0.02", "max_v_p = 1e-9", "thresholds.max_v_p"),
    ],
)
def test_thresholds_leaving_no_candidate(tmp_path, old, new, key):
    path, text = _variant(tmp_path, old, new)
    with pytest.raises(InputError, match="thresholds leave too few candidates") as err:
        make_plan(load_protocol(path), candidates=500)
    assert f"{path}:{_line_of(text, new)}: {key}" in str(err.value)


def test_hanging_mass_must_pull_down(tmp_path):
    text = UR_FILE.read_text().replace("direction = [0, 0, -1]", "direction = [0, 1, 0]")
    path = tmp_path / "ur.toml"
    path.write_text(text)
    with pytest.raises(InputError, match="pure force along -z0") as err:
        load_protocol(path)
    header = _line_of(text, 'name = "mass-10kg"') - 1
    assert f"{path}:{header}: load_cases[0]" in str(err.value)


def test_load_above_safety_limit(tmp_path):
    path, text = _variant(tmp_path, "max_force_N = 3200", "max_force_N = 3000")
    with pytest.raises(InputError, match=r"force 3111\.3 N exceeds safety.max_force_N") as err:
        load_protocol(path)
    line = _line_of(text, 'name = "eq22"')
    assert f"{path}:{line}: load_cases[0].name" in str(err.value)


def test_cli_reports_without_traceback(tmp_path, capsys):
    path, text = _variant(tmp_path, "repeats = 3", "repeats = 0")
    status = main(["plan", "--protocol", path, "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2
    assert "Traceback" not in err
    assert f"{path}:{_line_of(text, 'repeats = 0')}: campaign.repeats" in err


@pytest.mark.parametrize(
    ("old", "new", "key", "words"),
    [
        ('driver = "emscon"', 'driver = "emscom"', "instruments.pose.driver", "unknown driver"),
        ('address = "udp://192.168.1.1:49152"', 'address = "udp://192.168.1.1:port"',
         "instruments.force_torque.address", "bad address"),
    ],
)
def test_instrument_errors_name_key_and_line(tmp_path, old, new, key, words):
    path, text = _variant(tmp_path, old, new)
    with pytest.raises(InputError, match=words) as err:
        load_protocol(path)
    assert f"{path}:{_line_of(text, new)}: {key}" in str(err.value)


def test_cli_plan_writes_directory(tmp_path, capsys):
    out = tmp_path / "plan"
    status = main(["plan", "--protocol", str(KR_FILE), "--out", str(out), "--candidates",
                   "1000", "--strategy", "e-optimal", "--no-figure"])
    printed = capsys.readouterr().out
    assert status == 0
    assert "predicted standard error of k" in printed and "random" in printed
    assert len((out / "plan.csv").read_text().splitlines()) == 1 + 5
    assert (out / "protocol.toml").read_text() == KR_FILE.read_text()


def test_yaml_semantic_error_names_line(tmp_path):
    data = tomllib.loads(KR_FILE.read_text())
    data["thresholds"]["min_inv_kappa_F"] = 0.95
    path = tmp_path / "kr.yaml"
    text = yaml.safe_dump(data, sort_keys=False)
    path.write_text(text)
    with pytest.raises(InputError, match="best found 0.5") as err:
        make_plan(load_protocol(path), candidates=300)
    line = _line_of(text, "min_inv_kappa_F:")
    assert f"{path}:{line}: thresholds.min_inv_kappa_F" in str(err.value)


@pytest.mark.parametrize(("old", "new", "key", "words"), [
    ("force_N = [0, 2200, 2200]", "force_N = [-1e300, 2200, 2200]", "load_cases[0].force_N[0]",
     "-1e+300 N is implausible: expected |value| <= 100000 N"),
    ("moment_N_m = [200, 200, 0]", "moment_N_m = [200, 2e9, 0]", "load_cases[0].moment_N_m[1]",
     "2e+09 N m is implausible"),
    ("max_force_N = 3200", "max_force_N = 1e300", "safety.max_force_N", "implausible"),
    ("xyz_mm = [0, 0, 0]", "xyz_mm = [0, 0, 1e200]", "tool.xyz_mm[2]", "1e+200 mm is implausible"),
    ("mass_kg = 0", "mass_kg = 1e30", "tool.mass_kg", "less than or equal to 10000"),
    ("noise = { force_N = 0.5,", "noise = { force_N = 1e300,",
     "instruments.force_torque.noise.force_N", "less than or equal to 10000"),
    ("fixed_deg = { q1 = 0,", "fixed_deg = { q1 = 1e300,", "sampling.fixed_deg.q1",
     "1e+300 deg is implausible"),
])
def test_implausible_numbers_refused_by_plan(tmp_path, capsys, old, new, key, words):
    """One line naming file, line and key; exit 2; no warning; nothing written."""
    from tests.refusal import assert_refused

    path, text = _variant(tmp_path, old, new)
    assert text.count(new) == 1
    line = _line_of(text, new)
    err = assert_refused(capsys, ["plan", "--protocol", path, "--out", tmp_path / "out"],
                         f"{path}:{line}: {key}: ", watch=[tmp_path])
    assert words in err and "inf" not in err
