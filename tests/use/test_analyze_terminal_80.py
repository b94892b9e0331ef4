"""``campaign analyze`` read at 80 columns: the assumptions block wraps at words with a
hanging indent, the k table fits, k is in kN m/rad as in results.json / 1e3."""

from __future__ import annotations

import json

import pytest

from tests.use.conftest import analyze


def test_assumptions_wrap_with_a_hanging_indent(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    capsys.readouterr()
    out_dir = analyze(tmp_path, "a80")
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert all(len(line) <= 80 or len(line.split()) == 1 for line in lines), lines
    start = lines.index("Assumptions")
    block = []
    for line in lines[start + 1:]:
        if not line.startswith("  "):
            break
        block.append(line)
    items = [line for line in block if not line.startswith("    ")]
    assert [item.split(":")[0].strip() for item in items] == [
        "robot", "tool point P", "noise per test row", "method", "robust fitting",
        "wrench errors in variables", "poses", "held-out validation"]
    assert len(block) > len(items)  # some items wrapped, under their own indent
    # the wrapped noise item keeps every word whole
    noise = " ".join(" ".join(block).split()).split("noise per test row: ")[1]
    assert "encoders 5.04 urad" in noise and "mdeg" not in out
    res = json.loads((out_dir / "results.json").read_text())
    rows = {line.split("│")[1].strip(): line for line in lines
            if line.startswith("│") and line.split("│")[1].strip().startswith("k")}
    assert "95 % interval (kN m/rad)" in out
    assert len(rows) == 6
    for j, k in enumerate(res["joint_stiffness_Nm_per_rad"]):
        cell = rows[f"k{j + 1}"].split("│")[2]
        assert float(cell) == pytest.approx(k / 1e3, rel=1e-4)
