"""campaign analyze: CSV import, poses named in the protocol, and bad input (exit 2)."""

from __future__ import annotations

import json
from html.parser import HTMLParser

import numpy as np
import pytest
from report_runs import write_csv, write_run

import analysis.identification.problem as identification
from analysis.identification.estimate import analyze_table
from analysis.identification.io.csv_reader import read_csv
from analysis.model.robots import load_robot
from campaign.cli import main
from campaign.cli.commands import analyze as analyze_command


class _H3(HTMLParser):
    def __init__(self):
        super().__init__()
        self.titles, self._in = [], False

    def handle_starttag(self, tag, attrs):
        self._in = tag == "h3"

    def handle_data(self, data):
        if self._in:
            self.titles.append(data.strip())
            self._in = False


def test_cli_methods_match_the_identification():
    from analysis import choices
    from campaign.cli.terminal import Method

    assert identification.METHODS is choices.METHODS
    assert tuple(m.value for m in Method) == identification.METHODS
    assert analyze_command.DEFAULT_METHOD == identification.DEFAULT_METHOD


def test_csv_import_writes_the_same_result_keys_and_a_report(tmp_path, rows):
    csv = write_csv(tmp_path / "tests.csv", rows)
    out = tmp_path / "out"
    assert main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out",
                 str(out), "--method", "exact", "--trials", "20"]) == 0
    res = json.loads((out / "results.json").read_text())
    direct = analyze_table(read_csv(csv), load_robot("kr240-2"), method="exact").to_dict()
    # campaign analyze adds K_X at the tested poses and the model file (docs/use.md), and
    # the report ID (docs/report.md)
    assert list(res) == [*direct, "cartesian_stiffness", "model_file", "report_id"]
    np.testing.assert_allclose(res["joint_stiffness_Nm_per_rad"],
                               direct["joint_stiffness_Nm_per_rad"], rtol=1e-9)
    html = (out / "report.html").read_text(encoding="utf-8")
    assert f"csv: {csv}" in html
    assert "no data-quality flags are recorded with a CSV file" in html
    assert (out / "report.pdf").read_bytes()[:5] == b"%PDF-"
    assert json.loads((out / "analysis.json").read_text())["partial"] is False


def test_poses_named_in_the_protocol_get_kx(tmp_path, rows):
    extra = ('\n[report]\nposes_deg = { drilling = [0, 50, -200, 0, 60, 0] }\n'
             'wrench = [0, 0, -500, 0, 0, 0]\n')
    run = write_run(tmp_path / "run", rows, protocol_extra=extra)
    assert main(["analyze", str(run), "--trials", "20", "--out", str(tmp_path / "o")]) == 0
    parser = _H3()
    html = (tmp_path / "o" / "report.html").read_text(encoding="utf-8")
    parser.feed(html)
    assert "K_X at pose drilling, with K_C" in parser.titles
    assert "Effect of K_C (the load's geometric stiffness)" in parser.titles
    assert "f = (0, 0, -500) N, m = (0, 0, 0) N m (protocol [report] wrench)" in html


@pytest.mark.parametrize(
    "args, message",
    [
        ([], "give either RUN_DIR or --measurements"),
        (["{run}", "--measurements", "{csv}"], "give either RUN_DIR or --measurements"),
        (["{missing}"], "run directory not found"),
        (["--measurements", "{csv}", "--out", "{tmp}"], "--robot: --measurements needs --robot"),
        (["--measurements", "{csv}", "--robot", "kr240-2"], "--out: --measurements needs --out"),
        (["{run}", "--robot", "kr240-2"], "drop --robot"),
        (["{run}", "--method", "magic"],
         "Invalid value for '--method': Value error, 'magic' is not one of 'ols', 'wls', 'exact'"),
        (["{run}", "--joints", "1,9"], "--joints: joint 9 is out of range"),
        (["{run}", "--pose", "0,30,-190,10,40"], "--pose #1: expected 6 comma-separated"),
        (["{run}", "--pose", "0,300,-190,10,40,0"], "outside the joint limits"),
        (["{run}", "--wrench", "1,2,x,4,5,6"], "--wrench: item 3 ('x') is not a number"),
        (["{run}", "--trials", "3"], "--trials: need at least 10 trials"),
    ],
)
def test_bad_input_exits_2_with_a_message(tmp_path, rows, capsys, args, message):
    run = write_run(tmp_path / "run", rows)
    csv = write_csv(tmp_path / "t.csv", rows)
    subst = {"{run}": str(run), "{csv}": str(csv), "{tmp}": str(tmp_path / "o"),
             "{missing}": str(tmp_path / "nope")}
    argv = ["analyze", *[subst.get(a, a) for a in args]]
    assert main(argv) == 2
    err = capsys.readouterr().err
    # choices are checked by the command-line parser (usage error, listed by --help)
    assert err.startswith("error: " if "Invalid value" not in message else "Usage: ")
    assert message in err
    assert "Traceback" not in err


class _Rows(HTMLParser):
    """Rows of the residual table: (marked, cells)."""

    def __init__(self):
        super().__init__()
        self.rows, self._table, self._row, self._cell, self._marked = [], False, None, None, False
        self._title = ""

    def handle_starttag(self, tag, attrs):
        if tag == "table":
            self._table = self._title.startswith("Residuals")
        if tag == "tr" and self._table:
            self._row, self._marked = [], dict(attrs).get("class") == "marked"
        if tag == "td" and self._row is not None:
            self._cell = ""
        self._h3 = tag == "h3"

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None:
            self._row.append(self._cell)
            self._cell = None
        if tag == "tr" and self._row:
            self.rows.append((self._marked, self._row))
            self._row = None
        if tag == "table":
            self._table = False

    def handle_data(self, data):
        if getattr(self, "_h3", False):
            self._title = data.strip()
            self._h3 = False
        if self._cell is not None:
            self._cell += data


def test_an_outlier_is_marked_in_the_residual_table(tmp_path, rows, capsys):
    rows = [dict(r) for r in rows]
    rows[7]["dy_mm"] += 0.5  # 0.5 mm on one component: about 17 sigma
    out = tmp_path / "o"
    run = str(write_run(tmp_path / "run", rows))
    # chi-square p ~ 1e-14: refused, naming the glitch's tests.csv line first
    assert main(["analyze", run, "--trials", "10", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "misfit" in err and "worst rows: line 9 (pose P3) dy" in err
    assert "--accept-misfit" in err and not (out / "results.json").exists()
    assert main(["analyze", run, "--trials", "10", "--out", str(out), "--accept-misfit"]) == 0
    res = json.loads((out / "results.json").read_text())
    assert res["misfit_accepted"]["accepted"] and "misfit" in res["misfit_accepted"]["problems"][0]
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "ACCEPTED DESPITE A REFUSAL" in html and "Assumptions" in html
    parser = _Rows()
    parser.feed((out / "report.html").read_text(encoding="utf-8"))
    marked = [cells for m, cells in parser.rows if m]
    assert [c[0] for c in marked] == ["8"]  # test 8 = file line 9
    assert marked[0][4].endswith(" *") and float(marked[0][4][:-2]) > 300  # um
    res = json.loads((out / "results.json").read_text())
    flagged = [r for r in res["residuals"] if r["outlier"]]
    assert {(r["test"], r["component"]) for r in flagged} >= {(7, "dy")}


def test_ols_on_a_kr240_run_is_corrected_not_refused(tmp_path, complete_run, capsys):
    """The paper's estimator at w_eff on the KR240-2: the linearisation bias is corrected
    (exit 0), results.json has both estimates, and the corrected k agrees with the exact
    fit's to 1 standard error (they weight the tests differently: OLS and WLS of one data
    set differ by ~0.5 se) and with the truth to 3, where the raw one is > 3 off on k3."""
    out = {}
    for method in ("ols", "exact"):
        out[method] = tmp_path / method
        assert main(["analyze", str(complete_run), "--out", str(out[method]), "--method",
                     method, "--no-report"]) == 0
    printed = capsys.readouterr().out
    assert "raw ols" in printed and "linearisation bias corrected" in printed
    ols = json.loads((out["ols"] / "results.json").read_text())
    ex = json.loads((out["exact"] / "results.json").read_text())
    bias = ols["linearisation_bias"]
    assert bias["reliable"] and ex["linearisation_bias"] is None
    k, k_ex = (np.array(r["joint_stiffness_Nm_per_rad"]) for r in (ols, ex))
    se = np.array(ex["standard_error_Nm_per_rad"])
    raw = np.array(bias["raw_joint_stiffness_Nm_per_rad"])
    assert np.max(np.abs(raw - k_ex) / se) > 3
    assert np.max(np.abs(k - k_ex) / se) < 1.0, (k - k_ex) / se
    from report_runs import TRUE_K

    assert np.max(np.abs(k - TRUE_K) / np.array(ols["standard_error_Nm_per_rad"])) < 3
    np.testing.assert_allclose(bias["corrected_joint_stiffness_Nm_per_rad"], k, rtol=1e-12)


def test_unreliable_linear_correction_is_refused_unless_accepted(tmp_path, complete_run,
                                                                  monkeypatch):
    import analysis.identification.corrections.linear_bias as lb

    monkeypatch.setattr(lb, "CONTRACTION_LIMIT", 1e-9)
    args = ["analyze", str(complete_run), "--method", "ols", "--no-report"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    assert main([*args, "--out", str(tmp_path / "b"), "--accept-misfit"]) == 0
    res = json.loads((tmp_path / "b" / "results.json").read_text())
    assert res["misfit_accepted"]["accepted"]
    assert any(p.startswith("linearisation bias") for p in res["misfit_accepted"]["problems"])
    assert res["linearisation_bias"]["corrected"] is False
