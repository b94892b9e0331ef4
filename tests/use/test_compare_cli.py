"""campaign compare on two analysed campaigns: verdicts, signs, interval level."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from campaign.cli import main
from tests.use._campaigns import TRUE_K
from tests.use.conftest import analyze


@pytest.fixture(scope="module")
def soft_k2(tmp_path_factory):
    """Analysis directory of a second campaign whose k2 is 5 % softer."""
    soft = TRUE_K.copy()
    soft[1] *= 0.95
    return analyze(tmp_path_factory.mktemp("soft"), "soft", seed=9, k=soft), soft


def test_compare_finds_a_softer_k2_and_refuses_other_robots(identified, soft_k2, tmp_path,
                                                            capsys):
    other, soft = soft_k2
    capsys.readouterr()
    assert main(["compare", str(identified), str(other), "--json", "--plot",
                 str(tmp_path / "c.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    verdicts = {r["joint"]: r["verdict"] for r in out["joints"]}
    assert verdicts[2] == "changed"
    assert [v for j, v in verdicts.items() if j != 2] == ["no evidence of change"] * 5
    k2 = out["joints"][1]
    assert k2["relative_difference"] < -0.03
    lo, hi = k2["interval_difference_Nm_per_rad"]
    assert lo < soft[1] - TRUE_K[1] < hi
    assert (tmp_path / "c.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
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


def test_z_has_the_sign_of_the_change_of_k(identified, soft_k2, capsys):
    """z > 0 when B is stiffer: k2 5 % softer in B gives z2 < 0 (and swapping A, B flips it);
    |z| the compliance test, recomputed here from results.json's compliances."""
    other, _ = soft_k2
    capsys.readouterr()
    assert main(["compare", str(identified), str(other), "--json"]) == 0
    ab = json.loads(capsys.readouterr().out)
    assert main(["compare", str(other), str(identified), "--json"]) == 0
    ba = json.loads(capsys.readouterr().out)
    ra, rb = (json.loads((d / "results.json").read_text()) for d in (identified, other))
    xa, xb = (np.array(r["joint_compliance_rad_per_Nm"]) for r in (ra, rb))
    va, vb = (np.diag(r["covariance_of_compliance"]) for r in (ra, rb))
    z_expected = (1 / xb - 1 / xa) / np.abs(1 / xb - 1 / xa) * np.abs(xb - xa) / np.sqrt(va + vb)
    z = np.array([r["z"] for r in ab["joints"]])
    assert np.allclose(z, z_expected, rtol=1e-12)
    assert z[1] < -30  # k2: -5 % at about 40 standard errors
    assert np.all(np.sign(z) == np.sign([r["difference_Nm_per_rad"] for r in ab["joints"]]))
    assert np.allclose([r["z"] for r in ba["joints"]], -z, rtol=1e-12)


def test_intervals_are_at_the_verdicts_level(identified, soft_k2, tmp_path, capsys):
    """Half-width = Phi^-1(1 - alpha/(2 m)) sqrt(se_A^2 + se_B^2), the se taken from
    results.json's standard_error_Nm_per_rad; the level named in JSON, text and plot."""
    import matplotlib
    from scipy.stats import norm

    other, _ = soft_k2
    ra, rb = (json.loads((d / "results.json").read_text()) for d in (identified, other))
    se = np.hypot(ra["standard_error_Nm_per_rad"], rb["standard_error_Nm_per_rad"])
    diff = np.array(rb["joint_stiffness_Nm_per_rad"]) - np.array(ra["joint_stiffness_Nm_per_rad"])
    for alpha, m_text in ((0.05, "99.17 %"), (0.01, "99.83 %")):
        capsys.readouterr()
        assert main(["compare", str(identified), str(other), "--json", "--alpha",
                     str(alpha)]) == 0
        out = json.loads(capsys.readouterr().out)
        zc = norm.ppf(1 - alpha / 12)
        assert np.isclose(out["critical_z"], zc, rtol=1e-12)
        assert np.isclose(out["interval_level"], 1 - alpha / 6, rtol=1e-15)
        assert out["interval_level_text"].startswith(m_text)
        iv = np.array([r["interval_difference_Nm_per_rad"] for r in out["joints"]])
        assert np.allclose(iv[:, 0], diff - zc * se, rtol=1e-9)
        assert np.allclose(iv[:, 1], diff + zc * se, rtol=1e-9)
        # the interval excludes 0 exactly where the verdict says "changed"
        changed = np.array([r["verdict"] == "changed" for r in out["joints"]])
        assert np.array_equal(changed, (iv[:, 0] > 0) | (iv[:, 1] < 0))
    assert main(["compare", str(identified), str(other)]) == 0
    text = capsys.readouterr().out
    assert "99.17 % (Bonferroni: 1 - alpha/6, alpha 0.05 over 6 joints)" in text
    assert "95 %" not in text
    with matplotlib.rc_context({"svg.fonttype": "none"}):
        assert main(["compare", str(identified), str(other), "--plot",
                     str(tmp_path / "c.svg")]) == 0
    svg = (tmp_path / "c.svg").read_text()
    # the y label is mathtext (drawn glyph by glyph): the level is read in the title
    assert "intervals at 99.17 % = 1 - alpha/6" in svg


def test_campaigns_sharing_their_tests_are_refused(identified, tmp_path, capsys):
    """A copy of the analysis, the same CSV analysed again under other pose labels, and a
    campaign reusing 5 of A's 15 tests: refused; without tests_data, identical results are."""
    copy = tmp_path / "copy"
    shutil.copytree(identified, copy)
    capsys.readouterr()
    assert main(["compare", str(identified), str(copy)]) == 2
    assert "same tests" in capsys.readouterr().err
    # the same tests.csv imported again (pose labels renamed, rows reversed)
    src = identified.parent / "full.csv"
    lines = src.read_text().splitlines()
    again = tmp_path / "again.csv"
    again.write_text("\n".join([lines[0], *[ln.replace("P", "Q", 1) for ln in lines[:0:-1]]])
                     + "\n")
    from tests.use.conftest import SIGMAS

    assert main(["analyze", "--measurements", str(again), "--robot", "kr240-2", "--out",
                 str(tmp_path / "again"), "--no-report", *SIGMAS]) == 0
    capsys.readouterr()
    assert main(["compare", str(identified), str(tmp_path / "again")]) == 2
    assert "same tests" in capsys.readouterr().err
    # 5 of A's tests in a campaign of other tests: shared rows
    other = analyze(tmp_path, "other", seed=21)
    mixed = tmp_path / "mixed.csv"
    other_lines = (tmp_path / "other.csv").read_text().splitlines()
    mixed.write_text("\n".join([*other_lines[:11], *lines[11:]]) + "\n")
    assert main(["analyze", "--measurements", str(mixed), "--robot", "kr240-2", "--out",
                 str(tmp_path / "mixed"), "--no-report", *SIGMAS]) == 0
    capsys.readouterr()
    assert main(["compare", str(identified), str(tmp_path / "mixed")]) == 2
    assert "share tests (5 test row(s)" in capsys.readouterr().err
    assert main(["compare", str(other), str(identified)]) == 0  # independent: compared
    # results.json of an older version (no tests_data): identical results still refused,
    # different ones compared with a note
    for d in (copy, other):
        doc = json.loads((d / "results.json").read_text())
        del doc["tests_data"]
        (d / "results.json").write_text(json.dumps(doc))
    capsys.readouterr()
    assert main(["compare", str(identified), str(copy)]) == 2
    assert "identical stiffness and covariance" in capsys.readouterr().err
    assert main(["compare", str(identified), str(other)]) == 0
    assert "B's results.json has no tests_data" in capsys.readouterr().out


def test_a_run_and_its_tests_csv_imported_again_are_refused(tmp_path, capsys):
    """campaign analyze RUN and analyze --measurements RUN/tests.csv read the same tests
    through two readers: refused as one campaign."""
    from tests.report.report_runs import simulated_rows, write_run

    run = write_run(tmp_path / "run", simulated_rows(seed=4))
    assert main(["analyze", str(run), "--no-report"]) == 0
    assert main(["analyze", "--measurements", str(run / "tests.csv"), "--robot", "kr240-2",
                 "--out", str(tmp_path / "imported"), "--no-report",
                 "--translation-sigma-um", "36.742", "--rotation-sigma-urad", "24.495"]) == 0
    capsys.readouterr()
    assert main(["compare", str(run), str(tmp_path / "imported")]) == 2
    assert "same tests" in capsys.readouterr().err
    other = write_run(tmp_path / "other", simulated_rows(seed=5))
    assert main(["analyze", str(other), "--no-report"]) == 0
    assert main(["compare", str(run), str(other)]) == 0


def test_a_row_where_the_interval_and_the_z_test_part_is_marked():
    """k from 1 to 2 N m/rad (x 1 -> 0.5) with se of x 0.1 and 0.2: z = 0.5/sqrt(0.05) =
    2.236 on the compliances, while the delta-method interval of k_B - k_A = 1 has a
    standard error hypot(0.1, 0.8) = 0.806 (ratio 1.24): at z_c = 2 the verdict is
    "changed" and the interval holds 0, a borderline row said as such."""
    from scipy.stats import norm

    from analysis.identification.compare.comparison import Campaign, compare

    def campaign(name, k, se_x):
        kk = np.full(6, np.nan)
        kk[0] = k
        x = np.where(np.isfinite(kk), 1 / kk, np.nan)
        cov = np.zeros((6, 6))
        cov[0, 0] = se_x ** 2
        return Campaign(name, "arm", kk, x, cov, (0,),
                        tests_data={"sha256": name, "row_digests": [name]})

    alpha = 2 * norm.sf(2.0)
    out = compare(campaign("a", 1.0, 0.1), campaign("b", 2.0, 0.2), alpha)
    row = out["joints"][0]
    assert np.isclose(out["critical_z"], 2.0, rtol=1e-12)
    assert np.isclose(row["z"], 0.5 / np.sqrt(0.05), rtol=1e-12) and row["verdict"] == "changed"
    half = 2.0 * np.hypot(0.1, 0.8)
    assert np.allclose(row["interval_difference_Nm_per_rad"], [1 - half, 1 + half], rtol=1e-12)
    assert "borderline" in row["note"]
    # far from the border: no note
    out = compare(campaign("a", 1.0, 0.01), campaign("b", 1.1, 0.01), alpha)
    assert "note" not in out["joints"][0] and out["joints"][0]["z"] > 0


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
