"""The ABB IRB 6640 and FANUC R-2000iC protocols on the simulated lab: the real RWS and
RMI drivers move the fakes, and the identification recovers the lab's true stiffness."""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.acquire.progress import QuietReporter
from campaign.acquire.session import AcquireOptions, acquire
from campaign.cli import main
from campaign.planner import make_plan, write_plan
from campaign.protocol import load_protocol
from tests.acquire.conftest import ROOT


@pytest.mark.timeout(240)
@pytest.mark.parametrize("name, driver", [("r2000ic", "fanuc-rmi"), ("irb6640", "abb-rws")])
def test_fake_campaign_recovers_the_lab_stiffness(tmp_path, time_scale, name, driver):
    path = ROOT / "protocols" / f"{name}.toml"
    protocol = load_protocol(path)
    assert protocol.instruments["robot"].driver == driver
    truth = np.array(protocol.fake_lab.true_joint_stiffness)
    protocol.campaign.repeats = 1
    plan = tmp_path / "plan"
    write_plan(make_plan(protocol, candidates=2000), plan, figure=False)
    outcome = acquire(plan, tmp_path / "run", None,
                      AcquireOptions(fake=True, assume_yes=True, time_scale=time_scale),
                      QuietReporter(), say=lambda s: None)
    assert outcome.status == "complete", outcome.reason
    meta = json.loads((tmp_path / "run" / "metadata.json").read_text())
    assert json.dumps(meta).count(driver) >= 1
    assert main(["analyze", str(tmp_path / "run"), "--no-report", "--out",
                 str(tmp_path / "a")]) == 0
    res = json.loads((tmp_path / "a" / "results.json").read_text())
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    lo, hi = np.array(res["ci95_Nm_per_rad"]).T
    assert np.all(lo <= truth) and np.all(truth <= hi), (k, truth, lo, hi)
    assert np.all(np.abs(k / truth - 1) < 0.03)
