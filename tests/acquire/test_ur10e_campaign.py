"""The UR10e protocol on the simulated lab: the real ur-rtde client moves the fake UR
controller, a point tracker measures four reflectors in turn, the analysis weights the
rotations by the rigid fit's noise, and the identification recovers the lab's truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from analysis.errors import InputError
from analysis.identification.estimate import analyze_table
from campaign.cli import main
from campaign.protocol import load_protocol
from campaign.protocol_robot import protocol_robot
from campaign.run_format.reader import read_run
from campaign.run_noise import noise_from_protocol
from tests.acquire.conftest import ROOT, plan_and_acquire

PROTOCOL = ROOT / "protocols" / "ur10e.toml"


@pytest.mark.timeout(240)
def test_ur10e_fake_campaign(tmp_path, time_scale):
    protocol = load_protocol(PROTOCOL)
    truth = np.array(protocol.fake_lab.true_joint_stiffness)
    run_dir = plan_and_acquire(protocol, tmp_path, time_scale)
    run = read_run(run_dir)
    assert len(run.ok) == protocol.campaign.tests
    result = analyze_table(run.ok, protocol_robot(protocol), noise=noise_from_protocol(protocol),
                           validate=False)
    z = (result.k - truth) / result.se_k
    assert np.all(np.abs(z) < 4), (result.k, truth, result.se_k)
    # the rotation noise of the reflector fit is in the weights: residuals fit the model
    assert 0.3 < result.chi2_reduced < 2.5
    # tests.csv travels with its sidecar: re-imported alone it gives the run's k
    meta = json.loads((run_dir / "tests.meta.json").read_text())
    assert meta["tool"]["xyz_mm"] == [0.0, 0.0, 120.0] and meta["robot"]["key"] == "ur10e"
    assert main(["analyze", str(run_dir), "--no-report", "--out",
                 str(tmp_path / "a_run")]) == 0
    assert main(["analyze", "--measurements", str(run_dir / "tests.csv"),
                 "--no-report", "--out", str(tmp_path / "a_csv")]) == 0
    k_run, k_csv = (json.loads((tmp_path / d / "results.json").read_text())
                    ["joint_stiffness_Nm_per_rad"] for d in ("a_run", "a_csv"))
    np.testing.assert_allclose(k_csv, k_run, rtol=1e-9)


def test_reflectors_option_is_checked(tmp_path):
    text = PROTOCOL.read_text()
    start = text.index("options = { reflectors_mm")
    end = text.index("\n", start)
    bad = tmp_path / "bad.toml"
    bad.write_text(text[:start] + "options = { reflectors = 3 }" + text[end:])
    with pytest.raises(InputError, match="reflectors_mm"):
        load_protocol(bad).reflectors()
    two = tmp_path / "two.toml"
    two.write_text(text[:start] + "options = { reflectors_mm = { A = [0, 0, 0], "
                   "B = [100, 0, 0] } }" + text[end:])
    with pytest.raises(InputError, match="at least three"):
        load_protocol(two).reflectors()
