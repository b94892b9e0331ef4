"""campaign compare says what makes a 'changed' verdict less than a change of the robot:
different joint sets (a joint rigid in one fit moves the others: the audit compared a
six-joint exact fit with a translations-only ols fit kept by --accept-misfit and got
"changed" on k1..k3 with no note), different estimators, a result kept despite a refusal."""

from __future__ import annotations

import json

import numpy as np

from analysis.identification.compare.comparison import Campaign, compare
from analysis.identification.compare.load import load_campaign

K = np.array([1.4e6, 4.0e5, 9.3e5, 3.6e5, 3.7e5, 3.8e5])


def _campaign(name, joints, method="exact", accepted=False, scale=1.0):
    k = np.full(6, np.nan)
    k[list(joints)] = K[list(joints)] * scale
    x = np.where(np.isfinite(k), 1 / k, np.nan)
    cov = np.zeros((6, 6))
    for j in joints:
        cov[j, j] = (0.003 * x[j]) ** 2
    return Campaign(name, "arm", k, x, cov, tuple(joints),
                    tests_data={"sha256": name, "row_digests": [name]},
                    method=method, accepted=accepted)


def test_same_joints_same_method_no_caveat():
    out = compare(_campaign("a", range(6)), _campaign("b", range(6), scale=1.001))
    assert out["notes"] == []


def test_different_joint_sets_methods_and_an_accepted_refusal_are_said():
    out = compare(_campaign("a", range(6)),
                  _campaign("b", (0, 1, 2), method="ols", accepted=True, scale=0.98))
    assert [r["joint"] for r in out["joints"]] == [1, 2, 3]
    assert all(r["verdict"] == "changed" for r in out["joints"])  # 2 % at 0.3 % se
    notes = " | ".join(out["notes"])
    assert "A identified joints 1, 2, 3, 4, 5, 6, B joints 1, 2, 3" in notes
    assert "joint(s) 4, 5, 6 are taken as rigid" in notes
    assert "the estimators differ (A exact, B ols)" in notes
    assert "B was kept despite a refusal" in notes and "A was kept" not in notes
    assert len(out["notes"]) == 3


def test_method_and_acceptance_are_read_from_results_json(tmp_path):
    p = tmp_path / "results.json"
    doc = {"robot": "arm", "joint_stiffness_Nm_per_rad": [1e6, 2e6, 3e6, None, None, None],
           "joints_identified": [1, 2, 3],
           "covariance_of_compliance": (np.eye(3) * 1e-18).tolist(),
           "method": "wls", "misfit_accepted": {"accepted": True, "problems": ["misfit"]}}
    p.write_text(json.dumps(doc))
    c = load_campaign(p)
    assert c.method == "wls" and c.accepted is True and c.joints == (0, 1, 2)
    doc["robust"] = {"method": "huber", "constant": 1.345}
    p.write_text(json.dumps(doc))
    assert load_campaign(p).method == "wls, huber"
    doc["robust"] = None
    doc["misfit_accepted"] = {"accepted": False, "problems": []}
    del doc["method"]
    p.write_text(json.dumps(doc))
    c = load_campaign(p)
    assert c.method is None and c.accepted is False
