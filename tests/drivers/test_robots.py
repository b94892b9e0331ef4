"""Robot drivers: KUKA via KUKAVARPROXY fake, manual with a simulated operator, UR via ur-rtde."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, SafetyRefusal
from drivers.kuka_kvp import KukaVarProxyRobot
from drivers.manual import ManualLoad, ManualRobot
from drivers.roles import LoadCase
from drivers.sim.fake_kvp import FakeKukaVarProxy
from drivers.sim.lab import Lab
from drivers.sim.lab_load import LabOperator
from drivers.sim.settings import LabSettings
from drivers.ur import URRobot

pytestmark = pytest.mark.timeout(90)


@pytest.fixture
def kuka(world):
    fake = FakeKukaVarProxy(world)
    fake.start()
    drv = KukaVarProxyRobot(fake.url, timeout=1.0)
    drv.connect()
    yield fake, drv
    drv.close()
    fake.stop()


def test_kuka_reads_and_moves(kuka, world):
    _fake, drv = kuka
    q0 = drv.read_joints().value
    np.testing.assert_allclose(q0, world.joint_angles(), atol=1e-7)
    target = q0 + np.deg2rad([5, -3, 2, 10, -4, 7])
    reached = drv.move_joints(target, speed=0.5, acceleration=1.0)
    np.testing.assert_allclose(reached.value, target, atol=1e-7)  # 1e-5 deg on the wire
    np.testing.assert_allclose(world.joint_angles(), target, atol=1e-12)
    assert fake_var(kuka, "STIFF_VEL") == "34"  # ceil(100 * 0.5 / 1.5)


def fake_var(kuka, name):
    return kuka[0].vars[name]


def test_kuka_refused_variable_and_faults(kuka, world):
    fake, drv = kuka
    with pytest.raises(DeviceFault, match="no value for NO_SUCH_VAR: unknown variable"):
        drv.read_var("NO_SUCH_VAR")
    with pytest.raises(DeviceFault, match="refused the request for NO_SUCH_VAR"):
        drv.write_var("NO_SUCH_VAR", "1")
    with pytest.raises(DeviceFault, match=r"refused the request for \$AXIS_ACT"):
        drv.write_var("$AXIS_ACT", "{E6AXIS: A1 0}")  # read-only on the controller
    world.faults.inject(fake.device, "drop", 1)
    with pytest.raises(DeviceTimeout):
        drv.read_joints()
    np.testing.assert_allclose(drv.read_joints().value, world.joint_angles(), atol=1e-7)
    world.faults.inject(fake.device, "disconnect", 1)
    with pytest.raises(ConnectionFailed):
        drv.read_joints()


def test_kuka_bad_target_is_rejected_before_the_wire(kuka):
    _fake, drv = kuka
    with pytest.raises(ValueError, match="6 finite"):
        drv.move_joints(np.full(6, np.nan), 0.5, 1.0)


def test_manual_robot_with_a_simulated_operator(lab):
    op = LabOperator(lab.control_url, speed=2.0)
    try:
        robot = ManualRobot(ask=op.ask, say=op.say)
        load = ManualLoad(ask=op.ask, say=op.say)
        with robot, load:
            q0 = robot.read_joints().value
            target = q0 + np.deg2rad([3, 2, -2, 5, 5, -5])
            reached = robot.move_joints(target, 0.5, 1.0).value
            assert np.max(np.abs(reached - target)) < np.deg2rad(1e-3)  # typed to 1e-4 deg
            assert any(line.startswith("target (deg):") for line in op.lines)
            load.apply(LoadCase("down 500 N", np.array([0, 0, -500.0, 0, 0, 0])))
            np.testing.assert_allclose(lab.world.load(), [0, 0, -500, 0, 0, 0])
            load.remove()
            assert not np.any(lab.world.load())
    finally:
        op.close()


def test_manual_robot_asks_again_then_gives_up():
    answers = iter(["90 0 0", "1 2 3 4 5 6", "0 0 0 0 0 0"])
    said = []
    robot = ManualRobot(ask=lambda _: next(answers), say=said.append)
    q = robot.move_joints(np.zeros(6), 0.5, 1.0).value
    np.testing.assert_array_equal(q, np.zeros(6))
    assert any("not understood" in s for s in said)
    assert any("J6 is +6.00 deg from the target" in s for s in said)
    robot = ManualRobot(ask=lambda _: "oops", say=lambda _: None)
    with pytest.raises(DeviceFault, match="3 attempts"):
        robot.move_joints(np.zeros(6), 0.5, 1.0)
    robot = ManualRobot(ask=lambda _: "stop", say=lambda _: None)
    with pytest.raises(SafetyRefusal):
        robot.move_joints(np.zeros(6), 0.5, 1.0)


class ControlDouble:
    """Explicit test double of ``rtde_control.RTDEControlInterface`` (not the real client).

    It forwards ``moveJ`` straight to the simulated world, so the URRobot control
    path (caps, asynchronous moveJ, waiting on the receive side) is exercised
    with the state read back through real RTDE; the real control client against
    the fake controller is tested in ``test_ur_control_fake.py``.
    """

    def __init__(self, lab_client, accept=True):
        self.client, self.accept, self.calls = lab_client, accept, []

    def moveJ(self, q, speed, acceleration, asynchronous=False):  # noqa: N802 (ur-rtde's name)
        self.calls.append((list(q), speed, acceleration, asynchronous))
        if self.accept:
            duration = self.client.call("move", q=list(q), speed=speed)["duration"]
            if not asynchronous:
                time.sleep(duration + 0.05)
        return self.accept

    def stopJ(self, a, asynchronous=False):  # noqa: N802
        self.calls.append(("stop", a))

    def stopScript(self):  # noqa: N802
        self.calls.append(("stopScript",))

    def isConnected(self):  # noqa: N802
        return True

    def isProgramRunning(self):  # noqa: N802
        return True

    def disconnect(self):
        pass


@pytest.fixture(scope="module")
def ur_lab():
    settings = LabSettings(robot="ur10e", true_joint_stiffness=(2e5,) * 6, time_scale=200.0,
                           instruments=("robot",))
    with Lab(settings) as running:
        if "ur" not in running.addresses:
            pytest.skip(f"UR fake could not start: {running.notes}")
        yield running


def test_ur_receive_side_through_real_ur_rtde(ur_lab):
    from drivers.sim.control import LabClient

    with LabClient(ur_lab.control_url) as client:
        double = ControlDouble(client)
        robot = URRobot(ur_lab.addresses["ur"], control_factory=lambda host: double)
        with robot:
            q0 = robot.read_joints().value
            np.testing.assert_allclose(q0, ur_lab.world.joint_angles(), atol=1e-12)
            pose = robot.read_tool_pose().value
            np.testing.assert_allclose(pose, ur_lab.world.nominal_tool_pose(), atol=1e-9)
            target = q0 + np.deg2rad([10, -5, 5, 0, 3, 20])
            time.sleep(0.05)
            reached = robot.move_joints(target, speed=1.0, acceleration=2.0).value
            np.testing.assert_allclose(reached, target, atol=1e-12)
            assert double.calls[0][1:] == (1.0, 1.4, True)  # acceleration capped to 1.4 rad/s^2
            double.accept = False
            with pytest.raises(DeviceFault, match="refused"):
                robot.move_joints(target, 1.0, 2.0)
            client.call("fault", device="ur", fault="frozen", count=1)
            time.sleep(0.2)
            robot.timeout = 0.5
            with pytest.raises(DeviceTimeout, match="not updated"):
                for _ in range(3):  # the first read may still see the last package sent
                    robot.read_joints()


def test_ur_absent_controller_is_a_quick_connection_error():
    t0 = time.monotonic()
    with pytest.raises(ConnectionFailed):
        URRobot("ur://127.0.0.254", timeout=0.5).connect()
    assert time.monotonic() - t0 < 2


def test_kuka_stop_after_a_ctrl_c_between_request_and_reply(kuka, world, monkeypatch):
    """Ctrl-C while a reply is on its way: the stop that follows gets its own answer (the
    flaky-check's failure: 'could not stop the robot: KVP reply id 26 does not answer
    request 27', the robot reported not stopped)."""
    _fake, drv = kuka
    real = drv._recv_exact
    calls = []

    def interrupted(n):
        calls.append(n)
        if len(calls) == 1:
            raise KeyboardInterrupt  # the request is sent, its reply not read
        return real(n)

    monkeypatch.setattr(drv, "_recv_exact", interrupted)
    with pytest.raises(KeyboardInterrupt):
        drv.read_var("STIFF_GO")
    # the late reply comes first on a kept connection, whenever it arrives (TCP's order)
    drv.stop()  # ProtocolError there: reply id n-1 for request n
    assert fake_var(kuka, "STIFF_STOP") == "TRUE"
    np.testing.assert_allclose(drv.read_joints().value, world.joint_angles(), atol=1e-7)
