"""Robot files: loading, units, and clear errors for bad input."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot

KR = Path(__file__).resolve().parents[2] / "analysis/data/robots/kr240-2.toml"


def _write(tmp_path, text, name="arm.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def _mm_copy(tmp_path):
    """The KR240-2 file converted to millimetres by hand."""
    text = KR.read_text()
    text = text.replace('length_unit = "m"', 'length_unit = "mm"')
    for a, b in (("0.350", "350"), ("1.150", "1150"), ("0.041", "41"), ("1.200", "1200"),
                 ("0.215", "215"), ("0.682", "682")):
        text = text.replace(f"= {a}", f"= {b}")
    return _write(tmp_path, text)


def test_units_mm_equal_m(tmp_path):
    a = load_robot("kr240-2")
    b = load_robot(str(_mm_copy(tmp_path)))
    q = np.radians([10, 40, -100, 30, 50, 20])
    np.testing.assert_allclose(tool_pose(a, q), tool_pose(b, q), atol=1e-12)
    assert b.characteristic_length == pytest.approx(0.682)


def test_yaml_file_and_tool_offset(tmp_path):
    path = _write(tmp_path, """
        name: two-link test
        convention: standard_dh
        length_unit: mm
        angle_unit: deg
        joints:
          - {a: 100, alpha: 0, lower: -90, upper: 90}
          - {a: 100, lower: -90, upper: 90}
          - {lower: -90, upper: 90}
          - {lower: -90, upper: 90}
          - {lower: -90, upper: 90}
          - {lower: -90, upper: 90}
        tool: {xyz: [0, 0, 50]}
        sources: {geometry: test}
        """, "arm.yaml")
    r = load_robot(str(path))
    np.testing.assert_allclose(tool_pose(r, np.zeros(6))[:3, 3], [0.2, 0, 0.05], atol=1e-12)


@pytest.mark.parametrize(
    "edit, expected",
    [
        (('length_unit = "m"', 'length_unit = "inch"'), "length_unit"),
        (("d = 1.150", 'd = "long"'), "joints[2].d"),
        (("lower = -185\n", ""), "joints[0].lower: required key is missing"),
        (('name = "KUKA KR240-2"', 'name = "KUKA KR240-2"\ncolour = "orange"'),
         "colour: unknown key"),
        (("r = 0.215", "r = nan"), "joints[5].r"),
        (("alpha = 90\nd = 0.350", "alpha = 90\na = 0.2\nd = 0.350"), "not a modified_dh"),
    ],
)
def test_bad_robot_file_names_field_and_line(tmp_path, edit, expected):
    text = KR.read_text()
    assert edit[0] in text
    path = _write(tmp_path, text.replace(edit[0], edit[1], 1))
    with pytest.raises(InputError) as err:
        load_robot(str(path))
    msg = str(err.value)
    assert expected in msg
    assert str(path) in msg


def test_error_names_the_line(tmp_path):
    text = KR.read_text().replace("d = 1.150", 'd = "long"')
    line = text.splitlines().index('d = "long"') + 1
    path = _write(tmp_path, text)
    with pytest.raises(InputError, match=rf"{path}:{line}: joints\[2\]\.d"):
        load_robot(str(path))


def test_wrong_number_of_joints(tmp_path):
    text = KR.read_text()
    first = text.index("[[joints]]")
    second = text.index("[[joints]]", first + 1)
    path = _write(tmp_path, text[:first] + text[second:])
    with pytest.raises(InputError, match="joints"):
        load_robot(str(path))


def test_unknown_robot_and_missing_file():
    with pytest.raises(InputError, match="unknown robot 'kr999'"):
        load_robot("kr999")
    with pytest.raises(InputError, match="not found"):
        load_robot("/nonexistent/arm.toml")
    with pytest.raises(InputError, match="--tip"):
        load_robot("/nonexistent/arm.urdf")


def test_q_validation():
    r = load_robot("kr240-2")
    with pytest.raises(InputError, match="expected 6 joint angles"):
        r.check_q(np.zeros(5))
    with pytest.raises(InputError, match="finite"):
        r.check_q(np.array([0, 0, np.nan, 0, 0, 0]))


FANUC = Path(__file__).resolve().parents[2] / "analysis/data/robots/fanuc-s420f.toml"


def _coupled_fanuc(tmp_path, coupling="controller_coupling = { q2 = 1 }", limits="model"):
    """FANUC file whose pendant J3 is q3 + q2 (relative to the horizontal)."""
    text = FANUC.read_text()
    third = [i for i in range(len(text)) if text.startswith("[[joints]]", i)][2]
    text = text[:third] + "[[joints]]\n" + coupling + "\n" + text[third + len("[[joints]]\n"):]
    text = text.replace('limits_convention = "model"', f'limits_convention = "{limits}"')
    return _write(tmp_path, text)


def test_controller_coupling_round_trip(tmp_path):
    r = load_robot(str(_coupled_fanuc(tmp_path)))
    q = np.radians([10, 20, 30, 40, 50, 60])
    np.testing.assert_allclose(np.degrees(r.to_controller(q)), [10, 20, 50, 40, 50, 60])
    rng = np.random.default_rng(0)
    qs = rng.uniform(-1, 1, size=(7, 6))
    np.testing.assert_allclose(r.from_controller(r.to_controller(qs)), qs, atol=1e-14)
    # the kinematics do not change: only the pendant's numbers do
    plain = load_robot("fanuc-s420f")
    np.testing.assert_allclose(tool_pose(r, q), tool_pose(plain, q), atol=1e-12)


@pytest.mark.parametrize(
    "coupling, limits, message",
    [
        ("controller_coupling = { q3 = 1 }", "model", "coupled to itself"),
        ("controller_coupling = { q9 = 1 }", "model", "q1..q6"),
        ("controller_coupling = { q2 = 1 }", "controller", "limits_convention"),
    ],
)
def test_controller_coupling_errors(tmp_path, coupling, limits, message):
    with pytest.raises(InputError, match=message):
        load_robot(str(_coupled_fanuc(tmp_path, coupling, limits)))
