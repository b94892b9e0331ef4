"""The ABB IRB 6640 and FANUC R-2000iC protocols on the simulated lab: the real RWS and
RMI drivers move the fakes, and the identification recovers the lab's true stiffness."""

from __future__ import annotations

import json

import numpy as np
import pytest

from campaign.cli import main
from campaign.protocol import load_protocol
from tests.acquire.conftest import ROOT, plan_and_acquire


@pytest.mark.timeout(240)
@pytest.mark.parametrize("name, driver", [("r2000ic", "fanuc-rmi"), ("irb6640", "abb-rws"),
                                          ("irb6640", "abb-rws2")])
def test_fake_campaign_recovers_the_lab_stiffness(tmp_path, time_scale, name, driver):
    path = ROOT / "protocols" / f"{name}.toml"
    if driver == "abb-rws2":  # the same arm on an OmniCore controller (RWS 2.0)
        text = path.read_text().replace('driver = "abb-rws"', 'driver = "abb-rws2"')
        path = tmp_path / "irb6640-rw7.toml"
        path.write_text(text.replace("rws://Default%20User:robotics@", "rws2://Admin:robotics@"))
    protocol = load_protocol(path)
    assert protocol.instruments["robot"].driver == driver
    truth = np.array(protocol.fake_lab.true_joint_stiffness)
    run = plan_and_acquire(protocol, tmp_path, time_scale)
    robot = json.loads((run / "metadata.json").read_text())["instruments"]["robot"]
    assert robot["registry_name"] == driver
    if driver.startswith("abb"):  # the driver does not write the RWS password
        assert ":***@" in robot["address"] and "robotics" not in robot["address"]
    assert main(["analyze", str(run), "--no-report", "--out",
                 str(tmp_path / "a")]) == 0
    res = json.loads((tmp_path / "a" / "results.json").read_text())
    k = np.array(res["joint_stiffness_Nm_per_rad"])
    se = np.array(res["standard_error_Nm_per_rad"])
    # the noise draws depend on the polling (timing): a bound that fails once in ~1e4 runs
    # rather than the 95 % interval of each joint (all six hold in only ~74 % of runs)
    z = (k - truth) / se
    assert np.all(np.abs(z) < 4), (k, truth, se)
    assert np.all(np.abs(k / truth - 1) < 0.03)
