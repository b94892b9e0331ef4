"""A fake campaign with a tool: the load acts at the tool point, and identification with the
protocol's tool recovers the truth (without the tool it would not)."""

from __future__ import annotations

import numpy as np

from analysis.identification.estimate import analyze_table
from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot
from campaign.protocol import load_protocol
from campaign.protocol_robot import protocol_robot
from campaign.run_format.reader import read_run
from tests.acquire.conftest import PROTOCOL, displacement_noise, plan_and_acquire

TRUE_K = np.array([1409800, 400760, 935280, 360000, 370000, 380000], dtype=float)
TOOL = "xyz_mm = [30, -20, 250]\nrpy_deg = [0, 90, 0]"


def test_fake_campaign_with_tool_offset(tmp_path, time_scale):
    text = PROTOCOL.read_text().replace("xyz_mm = [0, 0, 0]\nrpy_deg = [0, 0, 0]", TOOL, 1)
    assert TOOL in text
    path = tmp_path / "kr240-tool.toml"
    path.write_text(text)
    protocol = load_protocol(path)
    robot = protocol_robot(protocol)
    # the tool moves P 250 mm along the flange axis (and 30, -20 mm across it)
    flange = load_robot("kr240-2")
    q = np.radians([0, 30, 10, 45, 45, 45])
    offset = np.linalg.inv(tool_pose(flange, q)) @ tool_pose(robot, q)
    np.testing.assert_allclose(offset[:3, 3], [0.030, -0.020, 0.250], atol=1e-12)

    run = read_run(plan_and_acquire(protocol, tmp_path, time_scale))
    noise = displacement_noise(protocol)
    result = analyze_table(run.ok, robot, noise=noise, validate=False)
    z = (result.k - TRUE_K) / result.se_k
    assert np.all(np.abs(z) < 4), (result.k, result.se_k)
    # arm joints: relative se 0.1-0.7 % with the worst-joint design (which spends tests on
    # the wrist), so 3 % is over 4 se for each of them
    assert np.all(result.se_k[:3] / result.k[:3] < 0.0075)
    assert np.max(np.abs(result.k[:3] / TRUE_K[:3] - 1)) < 0.03
    # the same data read with the flange as P is wrong by far more than its error bars
    wrong = analyze_table(run.ok, flange, noise=noise, validate=False, method="exact")
    assert np.max(np.abs(wrong.k / TRUE_K - 1)) > 0.1
