"""``campaign analyze --model``: the classes side by side in results.json, the chosen one's
k in place of the joint fit's; a bad name is a one-line error (exit 2)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np

from analysis.identification.io.columns import CSV_COLUMNS
from analysis.identification.io.measurements import table_from_arrays, to_csv_frame
from analysis.identification.noise import NoiseModel
from analysis.identification.studies import model_classes as mc
from analysis.report.model_classes import model_class_blocks
from campaign.cli import main


def _csv(tmp_path, lab_effects: str, seed: int = 4):
    robot, lab, k, loads, noise = mc.shop_lab()
    if lab_effects == "links":
        lab = replace(lab, lost_motion=None, compensator=None, gravity="off")
    # the analysis' default noise figures (no sidecar): the simulation uses them too
    tests, _ = mc.simulate(robot, lab, k, loads, 12, NoiseModel(), seed)
    frame = to_csv_frame(table_from_arrays(tests.pose, tests.q, tests.w, tests.d))
    csv = tmp_path / "tests.csv"
    frame[CSV_COLUMNS].to_csv(csv, index=False)
    return csv, k


def test_auto_on_compliant_links_chooses_links_and_reports_candidates(tmp_path, capsys):
    csv, k = _csv(tmp_path, "links")
    out = tmp_path / "out"
    rc = main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out", str(out),
               "--no-report", "--model", "auto"])
    assert rc == 0
    res = json.loads((out / "results.json").read_text())
    mcs = res["assumptions"]["model_classes"]
    printed = capsys.readouterr().out
    assert "Model classes (auto)" in printed and "chosen" in printed
    assert mcs["chosen"] == "links" and mcs["accepted"]
    assert "BIC" in mcs["rule"]
    names = [c["model"] for c in mcs["candidates"]]
    assert names[0] == "joints" and "links" in names
    chosen = next(c for c in mcs["candidates"] if c["model"] == "links")
    joints = mcs["candidates"][0]
    assert joints["chi2_nu"] > 20 and 0.7 < chosen["chi2_nu"] < 1.4
    assert 0.7 < chosen["heldout_chi2_nu"] < 1.4
    # not all 42 link entries are identifiable from 12 poses: the rest fixed and named
    kept = [p["name"] for p in chosen["parameters"]]
    fixed = ", ".join(f["parameter"] for f in chosen["fixed"]).split(", ")
    assert 20 < len(kept) < 42 and len(kept) + len(fixed) == 42
    assert all(f["why"] for f in chosen["fixed"])
    assert all(p["ci95"][0] < p["value"] < p["ci95"][1] for p in chosen["parameters"])
    # the report's tables: the candidates side by side, the chosen one's parameters
    cands, params = model_class_blocks(mcs)
    assert [r[0] for r in cands.rows] == names
    assert [r[-1] for r in cands.rows].count("chosen") == 1
    assert cands.rows[names.index("links")][-1] == "chosen"
    assert len(params.rows) == len(chosen["parameters"]) + len(chosen["fixed"])
    # model.toml carries the chosen class; every command reading it gets the links
    from analysis.kinetostatics.link_compliance import links_of
    from analysis.model.robot_files import load_robot_file

    robot = load_robot_file(out / "model.toml")
    assert robot.model_class["version"] == 2 and robot.model_class["name"] == "links"
    links = links_of(robot)
    assert [lc.link for lc in links] == [2, 3]
    c2 = links[0].matrix
    first = chosen["parameters"][0]
    a, b = (int(v) - 1 for v in first["name"][3:-1].split(","))
    assert first["name"].startswith("C2[") and c2[a, b] == c2[b, a] == first["value"]
    # and the kept entries' covariance (their se squared on the diagonal), with the
    # joints' cross-covariance: what the K_X and deflection intervals propagate
    from analysis.kinetostatics.link_compliance import link_covariance_of

    lnames, C_ll, C_xl = link_covariance_of(robot)
    assert list(lnames) == kept and C_ll.shape == (len(kept), len(kept)) and C_xl.shape == (
        6, len(kept))
    se = np.array([p["se"] for p in chosen["parameters"]])
    assert np.allclose(np.sqrt(np.diag(C_ll)), se, rtol=1e-12)
    assert np.allclose(C_ll, C_ll.T) and np.any(C_xl != 0)
    # results.json's k is the chosen class's; k1, k2 within 3 % of the lab's (k3..k6 carry
    # the link bending the tests cannot tell from them: the class's gauge)
    kk = np.array(res["joint_stiffness_Nm_per_rad"])
    assert np.allclose(kk, chosen["k_N_m_per_rad"])
    assert np.all(np.abs(kk[:2] / k[:2] - 1) < 0.03)


def test_unknown_model_class_is_a_one_line_error(tmp_path, capsys):
    csv, _ = _csv(tmp_path, "links")
    rc = main(["analyze", "--measurements", str(csv), "--robot", "kr240-2", "--out",
               str(tmp_path / "o"), "--no-report", "--model", "links+springs"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "springs" in err and "--model" in err
