"""The Runs list names an analysis written despite a refusal (``--accept-misfit``, or the
GUI's "Accept the refusal") as such, not as identified."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from campaign.jobs.runs import list_workspace


def _analysis(ws: Path, name: str, **extra) -> None:
    d = ws / name / "analysis"
    d.mkdir(parents=True)
    doc = {"robot": "KUKA KR240-2", "method": "ols", "n_tests": 6, "joints_identified": [1],
           "joint_stiffness_Nm_per_rad": [1.4e6], "ci95_Nm_per_rad": [[1.39e6, 1.41e6]],
           "warnings": ["a warning"], **extra}
    (d / "results.json").write_text(json.dumps(doc))


@pytest.mark.parametrize("extra,status", [
    ({"misfit_accepted": {"accepted": True, "problems": ["misfit: chi-square 6.1"]}},
     "accepted despite a refusal"),
    ({"misfit_accepted": {"accepted": False, "problems": []}}, "identified, with warnings"),
    ({}, "identified, with warnings"),
    ({"warnings": [], "misfit_accepted": {"accepted": False, "problems": []}}, "identified")])
def test_status_of_an_analysis(tmp_path, extra, status):
    _analysis(tmp_path, "run", **extra)
    (entry,) = list_workspace(tmp_path)
    assert (entry.kind, entry.path, entry.status) == ("analysis", "run/analysis", status)
    assert entry.k[0]["k_Nm_per_rad"] == 1.4e6
