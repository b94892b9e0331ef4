"""The simulated lab end to end: drivers built from its addresses, physics checked by analysis."""

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

from analysis.kinetostatics.equilibrium import displacement_screw
from drivers.errors import DeviceFault
from drivers.frames import matrix_to_rotvec, wrench_to_base
from drivers.registry import open_driver
from drivers.roles import LoadCase
from drivers.sim.control import LabClient
from drivers.sim.settings import KR240_STIFFNESS, LabSettings, settings_from_protocol

pytestmark = pytest.mark.timeout(90)
ROOT = Path(__file__).resolve().parents[2]


def test_loaded_displacement_follows_the_nonlinear_equilibrium(lab, settle):
    world = lab.world
    reflectors = {k: v for k, v in world.settings.reflectors.items() if k != "P"}
    robot = open_driver("kuka-kvp", lab.addresses["kuka-kvp"])
    tracker = open_driver("emscon", lab.addresses["emscon"], reflectors=reflectors,
                          aim=world.aim)
    sensor = open_driver("ati-netft", lab.addresses["ati-netft"])
    loads = open_driver("lab-load", lab.addresses["lab-load"])
    with robot, tracker, sensor, loads, LabClient(lab.control_url) as client:
        q = robot.read_joints().value + np.deg2rad([20, 10, -15, 30, 20, -40])
        robot.move_joints(q, speed=1.0, acceleration=2.0)
        sensor.tare(50)
        unloaded = tracker.measure_pose()
        w = np.array([1500.0, -800.0, -2500.0, 0.0, 0.0, 0.0])
        loads.apply(LoadCase("diagonal", w))
        settle(world)
        loaded = tracker.measure_pose()
        wrench = sensor.read_wrench(200)
        truth = client.call("truth")
        loads.remove()

    base_in_tracker = np.array(truth["base_in_tracker"])
    R_bt = base_in_tracker[:3, :3].T  # tracker -> base rotation
    measured_dp = R_bt @ (loaded.value[:3, 3] - unloaded.value[:3, 3])
    measured_rot = R_bt @ matrix_to_rotvec(loaded.value[:3, :3] @ unloaded.value[:3, :3].T)
    q_model = world.robot.from_controller(q)
    expected = displacement_screw(world.robot, q_model, np.array(KR240_STIFFNESS), w)
    assert np.linalg.norm(expected[:3]) > 2e-3  # a few millimetres: a meaningful check
    # reflector fit noise: ~tracker_noise / sqrt(3) per pose, twice
    assert np.linalg.norm(measured_dp - expected[:3]) < 6 * world.settings.tracker_noise
    assert np.linalg.norm(measured_rot - expected[3:]) < 6 * world.settings.tracker_noise / 0.1

    T = np.array(truth["tool_pose"])
    in_base = wrench_to_base(wrench.value, T, np.array(truth["sensor_mount"]), T[:3, 3])
    assert np.all(np.abs(in_base[:3] - w[:3]) < 0.5)
    assert np.all(np.abs(in_base[3:]) < 0.05)


def test_control_channel_commands_and_errors(lab):
    with LabClient(lab.control_url) as client:
        assert client.call("ping")["ok"]
        assert client.call("addresses")["addresses"]["emscon"] == lab.addresses["emscon"]
        state = client.call("state")
        assert len(state["q"]) == 6 and len(state["tcp_pose"]) == 6
        client.call("apply_load", wrench=[0, 0, -100, 0, 0, 0], name="w")
        assert client.call("state")["load"] == [0, 0, -100, 0, 0, 0]
        client.call("remove_load")
        client.call("aim", target="R2")
        assert client.call("state")["aimed"] == "R2"
        client.call("fault", device="geocom", fault="drop", count=2)
        assert client.call("take_fault", device="geocom", fault="drop")["armed"]
        client.call("clear_faults")
        assert not client.call("take_fault", device="geocom", fault="drop")["armed"]
        for cmd, fields, msg in [("fly", {}, "unknown command"),
                                 ("move", {"q": [0, 0]}, "joint"),
                                 ("move", {"q": [9.0] * 6}, "limits"),
                                 ("aim", {"target": "R9"}, "no reflector"),
                                 ("fault", {"device": "x", "fault": "melt"}, "unknown fault"),
                                 ("apply_load", {"wrench": [1, 2]}, "6 finite")]:
            with pytest.raises(DeviceFault, match=msg):
                client.call(cmd, **fields)
        assert client.call("ping")["ok"]  # still serving after bad requests


def test_settings_from_a_parsed_protocol():
    s = settings_from_protocol({"robot": "kr240-2", "seed": 3,
                                "lab": {"force_noise": 0.2, "true_joint_stiffness": [1e6] * 6},
                                "unrelated": 1}, time_scale=5.0, seed=None)
    assert (s.seed, s.time_scale, s.force_noise) == (3, 5.0, 0.2)
    assert s.true_joint_stiffness == (1e6,) * 6
    from analysis.errors import InputError

    with pytest.raises(InputError, match="stiffness"):
        LabSettings(true_joint_stiffness=(1.0, -1.0))
    with pytest.raises(InputError, match="unknown instruments"):
        LabSettings(instruments=("laser-cannon",))


def test_cli_refuses_without_fake_and_bad_inputs(tmp_path, capsys):
    from campaign.cli import main

    assert main(["lab"]) == 2
    err = capsys.readouterr().err
    assert "add --fake" in err and "Traceback" not in err
    assert main(["lab", "--fake", "--time-scale", "0"]) == 2
    assert "time scale" in capsys.readouterr().err
    bad = tmp_path / "p.toml"
    bad.write_text("robot = [unclosed")
    assert main(["lab", "--fake", "--protocol", str(bad)]) == 2
    assert "not valid TOML" in capsys.readouterr().err
    assert main(["lab", "--fake", "--protocol", str(tmp_path / "missing.toml")]) == 2
    assert "not found" in capsys.readouterr().err
    assert main(["lab", "--fake", "--instruments", "laser-cannon"]) == 2
    assert "unknown instruments" in capsys.readouterr().err


def test_cli_prints_addresses_serves_and_shuts_down(tmp_path):
    proto = tmp_path / "lab.toml"
    proto.write_text('robot = "kr240-2"\n[lab]\ntracker_noise = 2e-6\n')
    proc = subprocess.Popen(
        [sys.executable, "-m", "campaign", "lab", "--fake", "--protocol", str(proto),
         "--seed", "4", "--time-scale", "100", "--instruments", "geocom,robot"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        env=dict(os.environ))
    lines: queue.Queue[str] = queue.Queue()
    threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout], daemon=True).start()
    try:
        addresses = {}
        deadline = time.monotonic() + 40
        while time.monotonic() < deadline:
            try:
                line = lines.get(timeout=1.0).strip()
            except queue.Empty:
                continue
            if line == "ready":
                break
            name, _, url = line.partition("=")
            addresses[name] = url
        assert {"control", "geocom", "kuka-kvp", "lab-load"} <= set(addresses)
        with open_driver("geocom", addresses["geocom"]) as tracker, \
                open_driver("kuka-kvp", addresses["kuka-kvp"]) as robot:
            assert np.all(np.isfinite(tracker.measure_point().value))
            assert robot.read_joints().value.shape == (6,)
        with LabClient(addresses["control"]) as client:
            client.call("shutdown")
        assert proc.wait(timeout=15) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_rotated_sensor_mount_is_undone_by_wrench_to_base():
    from drivers.sim.world import World

    world = World(LabSettings(sensor_rotation=(0.3, -0.2, 1.0), sensor_offset=(0.01, 0.02, -0.1),
                              force_noise=0.0, torque_noise=0.0, settle_time=0.0))
    load = np.array([120.0, -30.0, -400.0, 5.0, -2.0, 1.0])
    world.apply_load(load)
    w_s = world.sensor_wrench()
    assert np.linalg.norm(w_s[:3] - load[:3]) > 10  # really expressed in another frame
    T = world.true_tool_pose()
    np.testing.assert_allclose(wrench_to_base(w_s, T, world.sensor_mount, T[:3, 3]), load,
                               atol=1e-9)


def test_streaming_fakes_state_their_deadline_real_addresses_keep_the_drivers(lab):
    """The simulated lab's streaming sensors state ``?timeout=`` (a starved simulation is
    not a device fault); an address without it keeps the driver's own deadline, and a
    bad value is one clear error."""
    from drivers.errors import AddressError
    from drivers.sim.lab import STREAM_DEADLINE_S

    url = lab.addresses["ati-netft"]
    assert url.endswith(f"&timeout={STREAM_DEADLINE_S:g}") and "http_port=" in url
    assert open_driver("ati-netft", url).timeout == STREAM_DEADLINE_S
    assert open_driver("ati-netft", "udp://192.168.1.1:49152").timeout == 1.0
    assert open_driver("ati-netft", "udp://192.168.1.1:49152?timeout=0.25").timeout == 0.25
    assert "timeout" not in lab.addresses["kuka-kvp"]  # not a streaming sensor
    with pytest.raises(AddressError, match="option timeout='soon' is not a number"):
        open_driver("ati-netft", "udp://192.168.1.1:49152?timeout=soon")
