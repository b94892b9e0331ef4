"""campaign compare on two analysed campaigns."""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.cli import main
from tests.use._campaigns import TRUE_K
from tests.use.conftest import analyze


def test_compare_finds_a_softer_k2_and_refuses_other_robots(identified, tmp_path, capsys):
    soft = TRUE_K.copy()
    soft[1] *= 0.95
    other = analyze(tmp_path, "soft", seed=9, k=soft)
    capsys.readouterr()
    assert main(["compare", str(identified), str(other), "--json", "--plot",
                 str(tmp_path / "c.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    verdicts = {r["joint"]: r["verdict"] for r in out["joints"]}
    assert verdicts[2] == "changed"
    k2 = out["joints"][1]
    assert k2["relative_difference"] < -0.03
    lo, hi = k2["ci95_difference_Nm_per_rad"]
    assert lo < soft[1] - TRUE_K[1] < hi
    assert (tmp_path / "c.png").is_file()
    same = analyze(tmp_path, "same", seed=10)
    capsys.readouterr()
    assert main(["compare", str(identified), str(same), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert np.isclose(out["critical_z"], 2.638, atol=1e-3)
    # another robot name in B: refused
    res = json.loads((same / "results.json").read_text())
    res["robot"] = "Universal Robots UR10e"
    (same / "results.json").write_text(json.dumps(res))
    assert main(["compare", str(identified), str(same)]) == 2
    assert "different robots" in capsys.readouterr().err
    # the same file twice is not two campaigns
    assert main(["compare", str(identified), str(identified / "results.json")]) == 2


def test_compare_rows_fit_80_columns(identified, tmp_path, capsys, monkeypatch):
    """The text table at 80 columns: every row on one line, k in kN m/rad as in --json."""
    same = analyze(tmp_path, "same80", seed=11)
    capsys.readouterr()
    monkeypatch.setenv("COLUMNS", "80")
    assert main(["compare", str(identified), str(same)]) == 0
    lines = capsys.readouterr().out.splitlines()
    # only a path longer than the line may overflow: it is never split
    assert all(len(line) <= 80 or len(line.split()) == 1 for line in lines), lines
    assert main(["compare", str(identified), str(same), "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    rows = [line.split() for line in lines if line.lstrip().startswith("k") and "[" in line]
    assert len(rows) == len(data["joints"]) == 6
    for row, joint in zip(rows, data["joints"], strict=True):
        assert row[0] == f"k{joint['joint']}"
        assert float(row[1]) == pytest.approx(joint["k_A_Nm_per_rad"] / 1e3, rel=1e-4)
        assert float(row[2]) == pytest.approx(joint["k_B_Nm_per_rad"] / 1e3, rel=1e-4)
        assert float(row[3]) == pytest.approx(100 * joint["relative_difference"], abs=0.006)
        assert " ".join(row[7:]) == joint["verdict"]
