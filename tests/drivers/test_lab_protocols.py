"""``campaign lab --fake --protocol P`` for every protocol shipped in protocols/.

The lab must simulate what the protocol describes: a fake for each instrument driver
of its ``[instruments]`` table (each answering the real driver), the ``[fake_lab]``
true stiffness, the robot with the protocol's tool, and the pose instrument's
reflectors. Checked against the protocol file itself and an independent forward
kinematics of the protocol's robot and tool.
"""

from __future__ import annotations

import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.model.kinematics import tool_pose
from analysis.model.robots import load_robot, with_tool
from campaign.protocol import load_protocol
from drivers.registry import open_driver
from drivers.sim.control import LabClient

pytestmark = pytest.mark.timeout(120)
ROOT = Path(__file__).resolve().parents[2]
PROTOCOLS = sorted(p for p in (ROOT / "protocols").iterdir()
                   if p.suffix in (".toml", ".yaml", ".yml"))
MANUAL = ("manual", "manual-load")


def _start(args: list[str]) -> tuple[subprocess.Popen, dict[str, str]]:
    """Start ``campaign lab`` and read its ``name=address`` lines up to ``ready``."""
    proc = subprocess.Popen([sys.executable, "-m", "campaign", "lab", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, env=dict(os.environ))
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
    addresses: dict[str, str] = {}
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=1.0).strip()
        except queue.Empty:
            if proc.poll() is not None:
                break
            continue
        if line == "ready":
            return proc, addresses
        name, _, url = line.partition("=")
        addresses[name] = url
    proc.kill()
    raise AssertionError(f"lab did not get ready: {proc.stderr.read()}")


def test_every_shipped_protocol_is_found():
    assert {p.name for p in PROTOCOLS} >= {"kr240-2.toml", "ur10e.toml"}


@pytest.mark.parametrize("path", PROTOCOLS, ids=lambda p: p.name)
def test_lab_simulates_the_protocol(path):
    protocol = load_protocol(path)
    proc, addresses = _start(["--fake", "--protocol", str(path), "--time-scale", "200"])
    try:
        # one fake per instrument driver of the protocol, each answering the real driver
        for role, spec in protocol.instruments.items():
            assert spec.driver in addresses, (role, spec.driver, sorted(addresses))
        with open_driver(protocol.instruments["robot"].driver,
                         addresses[protocol.instruments["robot"].driver]) as robot:
            q_ctrl = robot.read_joints().value
        with open_driver(protocol.instruments["force_torque"].driver,
                         addresses[protocol.instruments["force_torque"].driver]) as ft:
            assert np.all(np.isfinite(ft.read_wrench().value))
        pose_driver = protocol.instruments["pose"].driver
        with LabClient(addresses["control"]) as client:
            truth = client.call("truth")
            # the true stiffness is the protocol's [fake_lab] one
            np.testing.assert_allclose(truth["stiffness"],
                                       protocol.fake_lab.true_joint_stiffness, rtol=1e-12)
            # P is the protocol's tool point on the protocol's robot (independent FK)
            robot_model = with_tool(
                load_robot(protocol.campaign.robot),
                np.asarray(protocol.tool.xyz_mm, float) * 1e-3,
                np.radians(np.asarray(protocol.tool.rpy_deg, float)))
            expected = tool_pose(robot_model, robot_model.from_controller(q_ctrl))
            # encoders carry no noise here; the reported angles round to 1e-5 deg
            np.testing.assert_allclose(truth["nominal_tool_pose"], expected, atol=1e-6)
            reflectors = protocol.reflectors()
            if reflectors is not None:
                # each reflector the protocol names is where the lab puts one
                for name, xyz in reflectors.items():
                    client.call("aim", target=name)
                    with open_driver(pose_driver, addresses[pose_driver]) as tracker:
                        p = np.asarray(tracker.measure_point(name).value, float)
                    T = np.asarray(truth["base_in_tracker"]) @ np.asarray(truth["tool_pose"])
                    want = T[:3, :3] @ np.asarray(xyz) + T[:3, 3]
                    sigma = protocol.fake_lab.noise.translation_um * 1e-6
                    assert np.linalg.norm(p - want) < 8 * sigma + 1e-6, (name, p, want)
            else:
                with open_driver(pose_driver, addresses[pose_driver]) as tracker:
                    pose = np.asarray(tracker.measure_pose().value, float)
                assert pose.shape == (4, 4)
            client.call("shutdown")
        assert proc.wait(timeout=20) == 0
        err = proc.stderr.read()
        assert "Traceback" not in err, err
        k_line = next(line for line in err.splitlines() if "true joint stiffness" in line)
        assert "(kN m/rad)" in k_line  # the one format of k on the terminal
        assert f" {protocol.fake_lab.true_joint_stiffness[0] / 1e3:.5g}" in k_line
        assert f"tool xyz_mm {[float(v) for v in protocol.tool.xyz_mm]}" in err
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_protocol_without_fake_lab_and_robot_conflict_are_refused(tmp_path, capsys):
    from campaign.cli import main

    text = (ROOT / "protocols" / "kr240-2.toml").read_text()
    cut = tmp_path / "no_lab.toml"
    cut.write_text(text[: text.index("[fake_lab]")])
    assert main(["lab", "--fake", "--protocol", str(cut)]) == 2
    err = capsys.readouterr().err
    assert "[fake_lab]" in err and "Traceback" not in err
    assert main(["lab", "--fake", "--protocol", str(ROOT / "protocols" / "kr240-2.toml"),
                 "--robot", "ur5e"]) == 2
    assert "drop --robot" in capsys.readouterr().err


def test_protocol_that_is_not_utf8_is_refused_in_one_line(tmp_path, capsys):
    from campaign.cli import main

    text = (ROOT / "protocols" / "kr240-2.toml").read_text(encoding="utf-8")
    utf16 = tmp_path / "p.toml"
    utf16.write_bytes(text.encode("utf-16"))
    assert main(["lab", "--fake", "--protocol", str(utf16)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "UTF-16" in err and str(utf16) in err


@pytest.mark.parametrize("robot, driver, scheme", [("r2000ic", "fanuc-rmi", "rmi://"),
                                                   ("irb6640", "abb-rws", "rws://")])
def test_lab_robot_option_starts_the_brand_fake(robot, driver, scheme):
    proc, addresses = _start(["--fake", "--robot", robot, "--instruments", "robot",
                              "--time-scale", "200"])
    try:
        assert addresses[driver].startswith(scheme), addresses
        assert "kuka-kvp" not in addresses
        if driver == "abb-rws":  # an ABB arm: a RobotWare 6 and a RobotWare 7 controller
            assert addresses["abb-rws2"].startswith("rws2://Admin:robotics@127.0.0.1:")
            assert addresses["abb-rws2"].endswith("?insecure=1")
        with open_driver(driver, addresses[driver]) as drv:
            q = drv.read_joints().value
        with LabClient(addresses["control"]) as client:
            np.testing.assert_allclose(q, client.call("state")["q"], atol=1e-6)
            client.call("shutdown")
        assert proc.wait(timeout=20) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
