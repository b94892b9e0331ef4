"""The report of an ols/wls analysis shows the raw linear estimate beside the corrected one
(the audit found only a warning pointing to results.json): a table per joint whose numbers
are results.json `linearisation_bias`'s, with the correction's criterion and value."""

from __future__ import annotations

import json

import numpy as np
from report_html import ReportPage

from analysis.report.formatting import k_kNm
from campaign.cli import main


def test_ols_report_has_raw_and_corrected_k(complete_run, tmp_path):
    out = tmp_path / "ols"
    assert main(["analyze", str(complete_run), "--method", "ols", "--out", str(out),
                 "--trials", "20"]) == 0
    res = json.loads((out / "results.json").read_text())
    b = res["linearisation_bias"]
    page = ReportPage()
    page.feed((out / "report.html").read_text(encoding="utf-8"))
    rows = page.tables["Linearisation bias of ols: raw and corrected estimates"]
    assert rows[0][:3] == ["joint", "k reported (kN m/rad)", "raw ols (kN m/rad)"]
    body = rows[1:]
    assert [r[0] for r in body] == [f"k{j}" for j in range(1, 7)]
    for j, r in enumerate(body):
        assert r[1] == k_kNm(res["joint_stiffness_Nm_per_rad"][j])
        assert r[2] == k_kNm(b["raw_joint_stiffness_Nm_per_rad"][j])
        assert np.isclose(float(r[4]), b["bias_in_standard_errors"][j], atol=0.006)
        assert np.isclose(float(r[5].rstrip("%")), 100 * b["relative_change_of_k"][j],
                          atol=0.006)
    # the reported k is the corrected one, and it differs from the raw one
    assert np.allclose(res["joint_stiffness_Nm_per_rad"],
                       b["corrected_joint_stiffness_Nm_per_rad"], rtol=1e-12)
    assert body[2][1] != body[2][2]
    text = " ".join(" ".join(page.text).split())
    assert f"limit {b['contraction_limit']:g}), so k is the corrected estimate" in text


def test_exact_fit_has_no_linear_bias_table():
    from analysis.identification.estimate import identify
    from analysis.model.robots import load_robot
    from analysis.report.build import linear_bias_blocks
    from tests.identification._sim import simulate

    robot = load_robot("kr240-2")
    q = np.radians([[0, 30, -170, 45, 45, 45], [0, 50, -200, 45, 45, 45],
                    [0, 25, 20, 45, 45, 45], [0, 40, -230, 45, 45, 45]])
    w = np.array([0, 2200, 2200, 200, 200, 0.0])
    tests = simulate(robot, q, w, robot.nominal_stiffness)
    exact = identify(robot, tests, "exact", validate=False)
    assert linear_bias_blocks(exact) == []
    ols = identify(robot, tests, "ols", validate=False)
    (table,) = linear_bias_blocks(ols)
    assert len(table.rows) == 6 and table.title.startswith("Linearisation bias of ols")
