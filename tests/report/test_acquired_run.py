"""campaign analyze on a run written by the real ``campaign acquire --fake`` (opt-in: slow)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from report_runs import TRUE_K

from campaign.cli import main


@pytest.mark.slow
def test_demo_run_is_analysed_consistently_with_its_noise(tmp_path):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--quiet"]) == 0
    res = json.loads((out / "run" / "analysis" / "results.json").read_text())
    ci = np.array(res["ci95_Nm_per_rad"])
    # the noise model of the run rows (sqrt(1.5) x reading sigma) matches the data
    assert 0.4 < res["chi2_reduced"] < 2.5
    assert int(((ci[:, 0] <= TRUE_K) & (TRUE_K <= ci[:, 1])).sum()) >= 5
    html = (out / "run" / "analysis" / "report.html").read_text(encoding="utf-8")
    assert "PARTIAL RUN" not in html and "EmsconTracker" in html
