"""An integer longer than Python's int-string limit (4300 digits) in a TOML, YAML or JSON
file is refused in one line naming the file, line and key, never with a traceback
(the parsers raise a bare ValueError without a position)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.refusal import assert_refused

ROOT = Path(__file__).parents[2]
PROTOCOL = ROOT / "protocols" / "kr240-2.toml"
HUGE = "1" + "0" * 5000  # 5001 digits


def _line_of(text: str, needle: str) -> int:
    return next(i for i, line in enumerate(text.splitlines(), 1) if needle in line)


def test_protocol_with_a_huge_integer_refused_by_plan(tmp_path, capsys):
    text = PROTOCOL.read_text().replace("repeats = 3", f"repeats = {HUGE}", 1)
    path = tmp_path / "bad.toml"
    path.write_text(text)
    line = _line_of(text, HUGE)
    err = assert_refused(capsys, ["plan", "--protocol", path, "--out", tmp_path / "out"],
                         f"{path}:{line}: repeats: a number of 5001 digits", watch=[tmp_path])
    assert "4300" in err and len(err) < 400


def test_robot_file_with_a_huge_integer_in_an_inline_table_refused_by_plan(tmp_path, capsys):
    from analysis.model.robots import builtin_files

    robot = builtin_files()["kr240-2"].read_text()
    robot += f"\n[extra]\nnested = {{ a = 1, big = {HUGE}_0 }}\n"
    (tmp_path / "big.toml").write_text(robot)
    shutil.copy(PROTOCOL, tmp_path / "p.toml")
    p = tmp_path / "p.toml"
    p.write_text(p.read_text().replace('robot = "kr240-2"', 'robot = "big.toml"', 1))
    line = len(robot.splitlines())
    assert_refused(capsys, ["plan", "--protocol", p, "--out", tmp_path / "out"],
                   f"{tmp_path / 'big.toml'}:{line}: big: a number of 5002 digits",
                   watch=[tmp_path])


@pytest.mark.parametrize("name,text", [
    ("m.yaml", f"campaign:\n  name: x\n  tests: {HUGE}\n"),
    ("m.toml", f"[campaign]\nname = 'x'\ntests = {HUGE}\n"),
])
def test_read_mapping_file_names_line_and_key(tmp_path, name, text):
    from analysis.errors import InputError
    from analysis.file_errors import read_mapping_file

    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(InputError) as err:
        read_mapping_file(path, "protocol file")
    assert str(err.value).startswith(f"{path}:3: tests: a number of 5001 digits")


def test_read_json_object_names_line_and_key(tmp_path):
    from analysis.errors import InputError
    from analysis.file_errors import read_json_object

    path = tmp_path / "metadata.json"
    path.write_text('{\n  "status": "complete",\n  "n": [1, ' + HUGE + ']\n}\n')
    with pytest.raises(InputError) as err:
        read_json_object(path, "run record")
    assert str(err.value).startswith(f"{path}:3: n: a number of 5001 digits")


def test_numbers_under_the_limit_read_as_before(tmp_path):
    from analysis.file_errors import read_mapping_file

    path = tmp_path / "ok.toml"
    path.write_text(f"a = {'9' * 4300}\nb = 1_000\n")
    data, _ = read_mapping_file(path, "file")
    assert data["a"] == int("9" * 4300) and data["b"] == 1000
