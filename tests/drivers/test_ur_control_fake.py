"""The real ur-rtde control client (``rtde_control.RTDEControlInterface``) against the fake UR.

The fake controller (:mod:`drivers.sim.fake_rtde`, its own process) answers the
dashboard queries, takes the uploaded control program and emulates its register
protocol, so these tests run ur-rtde's own C++ client code. The client runs in
a child process of the test (``run_client``): ur-rtde blocks in C++, and a hang
there must fail the test on the subprocess timeout, not freeze the runner. The
lab (world and control channel) lives in the test process, so the tests read
the simulated robot directly.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from analysis.model.robots import load_robot
from drivers.sim.lab import Lab
from drivers.sim.settings import LabSettings
from drivers.ur import motion_time

pytest.importorskip("rtde_control")

pytestmark = pytest.mark.timeout(60)

ROOT = Path(__file__).resolve().parents[2]
TIME_SCALE = 10.0

PRELUDE = """
import json, os, sys, threading, time
import numpy as np
import rtde_control, rtde_receive
from drivers.ur import URRobot
from drivers.errors import DriverError
host, address = sys.argv[1], sys.argv[2]
out = {}
def say(**kw):
    print(json.dumps(kw), flush=True)
try:
"""
EPILOGUE = """
except Exception as err:
    out["error"] = type(err).__name__
    out["message"] = str(err)
    out["driver_error"] = isinstance(err, DriverError)
say(**out)
os._exit(0)  # skip ur-rtde's destructors (an abandoned call may still be blocked)
"""


def start_client(lab: Lab, body: str, address: str | None = None) -> subprocess.Popen:
    """Start a child Python running ``body`` (indented by 4) with ``host`` and ``address``."""
    code = PRELUDE + "\n".join("    " + line for line in body.strip("\n").splitlines()) + EPILOGUE
    url = lab.addresses["ur"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]))
    return subprocess.Popen([sys.executable, "-c", code, url.removeprefix("ur://"),
                             address or url], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env)


def read_line(proc: subprocess.Popen, timeout: float) -> dict:
    """Next JSON line of the child, failing (and killing it) after ``timeout`` s.

    ur-rtde writes its own messages to stdout too; lines that are not JSON are skipped.
    """
    deadline = time.monotonic() + timeout
    while True:
        ready, _, _ = select.select([proc.stdout], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            proc.kill()
            pytest.fail(f"ur-rtde client gave no answer within {timeout} s: {proc.stderr.read()}")
        line = proc.stdout.readline()
        if not line:
            proc.wait(5)
            pytest.fail(f"ur-rtde client ended without an answer: {proc.stderr.read()}")
        if line.startswith("{"):
            return json.loads(line)


def run_client(lab: Lab, body: str, address: str | None = None, timeout: float = 20.0) -> dict:
    proc = start_client(lab, body, address)
    try:
        out = read_line(proc, timeout)
        assert "error" not in out, out
        return out
    finally:
        proc.kill()
        proc.wait(5)


def ur_settings(time_scale: float = TIME_SCALE) -> LabSettings:
    return LabSettings(robot="ur10e", true_joint_stiffness=(2e5,) * 6, time_scale=time_scale,
                       instruments=("robot",))


@pytest.fixture(scope="module")
def ur_lab():
    with Lab(ur_settings()) as running:
        if "ur" not in running.addresses:
            pytest.skip(f"UR fake could not start: {running.notes}")
        yield running


def test_sync_movej_returns_with_the_robot_at_the_target(ur_lab):
    q0 = ur_lab.world.joint_angles()
    target = q0 + np.deg2rad([10, -5, 5, 0, 3, 20])
    v, a = 0.5, 1.0
    out = run_client(ur_lab, f"""
ctrl = rtde_control.RTDEControlInterface(host)
rx = rtde_receive.RTDEReceiveInterface(host, 125.0, ["timestamp", "actual_q"])
out["running"] = ctrl.isProgramRunning()
t0 = time.monotonic()
out["ok"] = ctrl.moveJ({target.tolist()}, {v}, {a})
out["wall"] = time.monotonic() - t0
time.sleep(0.03)  # one more package on the receive connection
out["q"] = rx.getActualQ()
ctrl.stopScript()
out["running_after_stop"] = ctrl.isProgramRunning()
""")
    assert out["running"] is True and out["ok"] is True
    # every joint exactly at the target: doubles in RTDE registers, no rounding on the way
    np.testing.assert_allclose(ur_lab.world.joint_angles(), target, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["q"], target, rtol=0, atol=1e-12)
    # moveJ returned only when the time-scaled trapezoid (0.349 rad at 0.5 rad/s) was over
    expected = motion_time(float(np.max(np.abs(target - q0))), v, a) / TIME_SCALE
    assert expected == pytest.approx(0.1198, abs=1e-3)
    assert expected <= out["wall"] < expected + 0.5
    assert not ur_lab.world.moving()
    assert out["running_after_stop"] is False


def test_driver_moves_reads_back_and_caps_speed_and_acceleration(ur_lab):
    q0 = ur_lab.world.joint_angles()
    target = q0 + np.deg2rad([-12, 8, 6, -4, 5, 15])
    out = run_client(ur_lab, f"""
calls = []
class Recorder:
    def __init__(self, real):
        self.real = real
    def moveJ(self, *args):
        calls.append(list(args[1:]))
        return self.real.moveJ(*args)
    def __getattr__(self, name):
        return getattr(self.real, name)
robot = URRobot(address, control_factory=lambda h: Recorder(rtde_control.RTDEControlInterface(h)))
with robot:
    peak = []
    def sample():
        while not done.is_set():
            peak.append(max(abs(v) for v in robot._rx.getActualQd()))
            time.sleep(0.002)
    done = threading.Event()
    threading.Thread(target=sample, daemon=True).start()
    t0 = time.monotonic()
    reached = robot.move_joints({target.tolist()}, speed=3.0, acceleration=30.0)
    out["reached"] = reached.value.tolist()
    out["wall"] = time.monotonic() - t0
    done.set()
    out["peak"] = max(peak)
    out["again"] = robot.read_joints().value.tolist()
out["calls"] = calls
""", address=ur_lab.addresses["ur"] + "?max_speed=0.2&max_acceleration=0.5")
    assert out["calls"] == [[0.2, 0.5, True]]  # capped before the call, asynchronous moveJ
    np.testing.assert_allclose(out["reached"], target, rtol=0, atol=1e-12)  # getActualQ
    np.testing.assert_allclose(out["again"], target, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ur_lab.world.joint_angles(), target, rtol=0, atol=1e-12)
    # the controller ran the capped profile: joint speed at most 0.2 rad/s, cruising near it,
    # and the motion took its time-scaled duration, three times what 3 rad/s would take
    assert 0.18 <= out["peak"] <= 0.2 + 1e-9
    distance = float(np.max(np.abs(target - q0)))
    capped = motion_time(distance, 0.2, 0.5) / TIME_SCALE
    assert motion_time(distance, 3.0, 30.0) / TIME_SCALE < capped / 3
    assert capped <= out["wall"] < capped + 1.0


def test_stopj_brings_the_robot_to_rest_short_of_the_target(ur_lab):
    q0 = ur_lab.world.joint_angles()
    target = q0 + np.array([0.6, 0.0, 0.0, 0.0, 0.0, 0.3])
    v, dec = 0.3, 2.0
    out = run_client(ur_lab, f"""
ctrl = rtde_control.RTDEControlInterface(host)
rx = rtde_receive.RTDEReceiveInterface(host, 500.0, ["timestamp", "actual_q", "actual_qd"])
q0 = np.array({q0.tolist()})
out["ok"] = ctrl.moveJ({target.tolist()}, {v}, 1.0, True)
t0 = time.monotonic()
while abs(rx.getActualQ()[0] - q0[0]) < 0.2 and time.monotonic() - t0 < 5:
    time.sleep(0.001)
out["s_call"] = rx.getActualQ()[0] - q0[0]
out["qd_call"] = rx.getActualQd()[0]
ctrl.stopJ({dec})
t0 = time.monotonic()  # braking takes 0.15 s of robot time; a loaded machine may lag
while any(abs(v) > 0 for v in rx.getActualQd()) and time.monotonic() - t0 < 5:
    time.sleep(0.005)
time.sleep(0.02)
out["q"] = rx.getActualQ()
out["qd"] = rx.getActualQd()
time.sleep(0.1)
out["q_later"] = rx.getActualQ()
ctrl.stopScript()
""")
    assert out["ok"] is True
    q = np.asarray(out["q"])
    s_rest = q[0] - q0[0]
    assert out["qd_call"] == pytest.approx(v, abs=1e-9)  # cruising when stopJ was sent
    # braking at 2 rad/s^2 from 0.3 rad/s takes v^2 / (2 a) = 0.0225 rad, plus the
    # distance covered before the command reached the controller (a few ms of wall time)
    assert out["s_call"] + 0.0225 - 1e-9 <= s_rest < out["s_call"] + 0.0225 + 0.2
    assert s_rest < 0.6 - 0.1
    np.testing.assert_allclose(q[5] - q0[5], 0.5 * s_rest, atol=1e-12)  # joints in step
    np.testing.assert_allclose(out["qd"], 0.0, atol=1e-12)
    np.testing.assert_array_equal(out["q_later"], out["q"])
    np.testing.assert_allclose(ur_lab.world.joint_angles(), q, rtol=0, atol=1e-12)


def test_driver_stop_interrupts_move_joints(ur_lab):
    q0 = ur_lab.world.joint_angles()
    target = q0 + np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.8])
    out = run_client(ur_lab, f"""
robot = URRobot(address)
with robot:
    start = robot.read_joints().value[5]  # fresh state (not the zeros before the first)
    def stop_once_moving():
        # on the robot's state, not after a fixed time: a loaded machine may start the
        # motion late (a 0.15 s sleep once stopped it 0.044 rad along)
        end = time.monotonic() + 60
        try:
            while robot.read_joints().value[5] - start < 0.1 and time.monotonic() < end:
                time.sleep(0.005)
            robot.stop()
        except Exception as err:  # shown by the assertion below
            out["stopper"] = repr(err)
    threading.Thread(target=stop_once_moving, daemon=True).start()
    try:
        robot.move_joints({target.tolist()}, speed=0.3, acceleration=1.0)
    except DriverError as err:
        out["raised"] = type(err).__name__
        out["message"] = str(err)
    out["q"] = robot.read_joints().value.tolist()
""")
    assert out.get("raised") == "DeviceFault" and "stop()" in out["message"], out
    assert "stopper" not in out, out
    travelled = out["q"][5] - q0[5]
    # stopped once 0.1 rad along (plus 0.0225 rad of braking: the driver's stopJ at
    # 2 rad/s^2 from 0.3 rad/s), at rest well short of the 0.8 rad target
    assert 0.1 + 0.0225 - 1e-6 <= travelled < 0.8 - 0.1
    np.testing.assert_allclose(ur_lab.world.joint_angles(), out["q"], rtol=0, atol=1e-12)


def test_refused_target_stops_the_program_and_the_next_move_uploads_it_again(ur_lab):
    robot_model = load_robot("ur10e")
    q0 = ur_lab.world.joint_angles()
    beyond = q0.copy()
    beyond[0] = robot_model.to_controller(robot_model.upper)[0] + 0.5
    target = q0 + np.deg2rad([3, 0, 0, 0, 0, 0])
    out = run_client(ur_lab, f"""
with URRobot(address) as robot:
    try:
        robot.move_joints({beyond.tolist()}, speed=0.5, acceleration=1.0)
    except DriverError as err:
        out["raised"] = type(err).__name__
        out["message"] = str(err)
    out["reached"] = robot.move_joints({target.tolist()}, 0.5, 1.0).value.tolist()
""")
    assert out["raised"] == "DeviceFault" and "refused" in out["message"]
    np.testing.assert_allclose(out["reached"], target, rtol=0, atol=1e-12)


@pytest.mark.timeout(40)
def test_disconnect_mid_move_is_a_driver_error_within_the_timeout():
    with Lab(ur_settings(time_scale=2.0)) as lab:
        if "ur" not in lab.addresses:
            pytest.skip(f"UR fake could not start: {lab.notes}")
        q0 = lab.world.joint_angles()
        target = q0 + np.array([0.5, 0.0, 0.0, 0.0, 0.0, 0.0])
        proc = start_client(lab, f"""
robot = URRobot(address, timeout=1.0)
robot.connect()
robot._control()  # connect the control side before the motion
say(ready=True)
t0 = time.monotonic()
try:
    robot.move_joints({target.tolist()}, speed=0.1, acceleration=1.0)  # 5 s real, 2.5 s wall
except DriverError as err:
    out["raised"] = type(err).__name__
    out["message"] = str(err)
out["elapsed"] = time.monotonic() - t0
""")
        try:
            assert read_line(proc, 20.0) == {"ready": True}
            time.sleep(0.5)
            assert lab.world.moving()
            lab.world.faults.inject("ur", "disconnect", 1)
            t_fault = time.monotonic()
            out = read_line(proc, 10.0)
            delay = time.monotonic() - t_fault
        finally:
            proc.kill()
            proc.wait(5)
    assert out.get("raised") in ("ConnectionFailed", "DeviceTimeout"), out
    assert delay < 1.0 + 1.5  # the driver's timeout (1 s) plus polling and shutdown
    assert out["elapsed"] < 2.0  # well before the motion would have ended (2.5 s)


def test_input_recipe_codec_and_motion_profile():
    import struct

    from drivers import rtde
    from drivers.errors import ProtocolError
    from drivers.sim.fake_ur_control import Profile

    names = ["input_int_register_0", "input_double_register_47", "external_force_torque",
             "input_bit_register_64", "input_double_register_48", "input_bit_register_63"]
    assert [rtde.input_type(n) for n in names] == ["INT32", "DOUBLE", "VECTOR6D", "BOOL",
                                                   "NOT_FOUND", "NOT_FOUND"]
    assert rtde.decode_names(b"input_int_register_0,input_double_register_0,") == [
        "input_int_register_0", "input_double_register_0"]
    # MOVEJ as ur-rtde packs it for its recipe 1: command, 6 joints, speed, acceleration, async
    body = struct.pack(">i8di", 1, 0.1, -0.2, 0.3, -0.4, 0.5, -0.6, 1.05, 1.4, 1)
    types = ["INT32"] + ["DOUBLE"] * 8 + ["INT32"]
    assert rtde.unpack_values(types, body) == [1, 0.1, -0.2, 0.3, -0.4, 0.5, -0.6, 1.05, 1.4, 1]
    with pytest.raises(ProtocolError):
        rtde.unpack_values(types, body[:-1])
    with pytest.raises(ProtocolError):
        rtde.unpack_values(types, body + b"\x00")
    # 0.3 rad at 0.2 rad/s, 0.5 rad/s^2: 0.4 s ramps, 1.1 s cruise
    p = Profile(0.3, 0.2, 0.5)
    assert p.end == pytest.approx(1.9)
    assert p.at(0.4) == pytest.approx((0.04, 0.2))
    assert p.at(1.7) == pytest.approx((0.3 - 0.5 * 0.5 * 0.2**2, 0.1))
    assert p.at(5.0) == (0.3, 0.0)
    p.stop(1.0, 2.0)  # from 0.16 rad at 0.2 rad/s, 0.01 rad to rest
    assert (p.length, p.end) == pytest.approx((0.17, 1.1))
    assert p.at(1.05) == pytest.approx((0.16 + 0.2 * 0.05 - 0.5 * 2.0 * 0.05**2, 0.1))
    short = Profile(0.01, 1.0, 1.0)  # triangular: the speed peaks at 0.1 rad/s
    assert short.end == pytest.approx(0.2)
    assert short.at(0.1) == pytest.approx((0.005, 0.1))
