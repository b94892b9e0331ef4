"""FANUC RMI: codec bytes, the driver's transcript against the fake, faults, and an
independent RMI client library (``fanuc-rmi`` from PyPI, used unchanged) on the fake."""

from __future__ import annotations

import socket

import numpy as np
import pytest

from drivers import rmi
from drivers.errors import (
    AddressError,
    ConnectionFailed,
    DeviceFault,
    DeviceTimeout,
    ProtocolError,
)
from drivers.fanuc_rmi import FanucRMIRobot
from drivers.sim.fake_rmi import FakeRMI
from drivers.sim.settings import LabSettings
from drivers.sim.world import World
from tests.model.test_abb_fanuc_models import R2000IC_URDF, fanuc_urdf_angles, urdf_tool0


@pytest.fixture
def fanuc():
    world = World(LabSettings(robot="r2000ic", seed=3, time_scale=200.0,
                              true_joint_stiffness=(1e6,) * 6))
    fake = FakeRMI(world)
    fake.start()
    drv = FanucRMIRobot(fake.url + "?motion_timeout=5", timeout=0.5)
    yield fake, drv, world
    drv.close()
    fake.stop()


def test_codec_bytes():
    assert rmi.encode({"Communication": "FRC_Connect"}) == b'{"Communication":"FRC_Connect"}\r\n'
    assert rmi.decode(b'{"Command" : "FRC_Abort", "ErrorID" : 0}\r\n') == {
        "Command": "FRC_Abort", "ErrorID": 0}
    assert rmi.kind({"Instruction": "FRC_WaitTime"}) == ("Instruction", "FRC_WaitTime")
    assert rmi.rmit(29) == 2556957 and rmi.error_name(2556957) == \
        "RMIT-029 Invalid sequence ID number"
    assert rmi.error_name(7004) == "ErrorID 7004"
    obj = rmi.joint_object(np.radians([1, -2.5, 3, 0, 90, -180]))
    assert obj == {"J1": 1.0, "J2": -2.5, "J3": 3.0, "J4": 0.0, "J5": 90.0, "J6": -180.0,
                   "J7": 0.0, "J8": 0.0, "J9": 0.0}
    np.testing.assert_allclose(np.degrees(rmi.joint_angles({"JointAngle": obj})),
                               [1, -2.5, 3, 0, 90, -180])
    for bad in (b"[1, 2]\r\n", b"{nope\r\n", b"\xff\r\n"):
        with pytest.raises(ProtocolError):
            rmi.decode(bad)
    with pytest.raises(ProtocolError, match="J1..J6"):
        rmi.joint_angles({"JointAngle": {"J1": 0}})
    with pytest.raises(AddressError, match="rmi://"):
        FanucRMIRobot("socket://1.2.3.4:16001")
    T = rmi.position_matrix({"Position": {"X": 1000, "Y": -20, "Z": 5, "W": 90, "P": 0,
                                          "R": 90}})
    np.testing.assert_allclose(T[:3, 3], [1.0, -0.02, 0.005])
    # W about x first, then R about the fixed z: x -> y, y -> z, z -> x
    np.testing.assert_allclose(T[:3, :3], [[0, 0, 1], [1, 0, 0], [0, 1, 0]], atol=1e-12)


def test_transcript_connect_read_move_close(fanuc):
    fake, drv, world = fanuc
    drv.connect()
    assert drv.session_port == fake.session.port != fake.port
    q0 = drv.read_joints().value
    np.testing.assert_allclose(q0, world.joint_angles(), atol=1e-6)
    target = q0 + np.radians([2.0, -1.0, 3.0, 0.0, 4.0, -5.0])
    reached = drv.move_joints(target, 0.5, 1.0).value
    np.testing.assert_allclose(reached, target, atol=np.radians(1e-4))
    pose = drv.read_tool_pose()
    expect = world.nominal_tool_pose()
    expect[2, 3] -= 0.670  # FANUC's world frame: at J2's height (ROS-Industrial's "base")
    np.testing.assert_allclose(pose.value, expect, atol=2e-6)
    assert (pose.frame, pose.child) == ("uframe 0", "utool 1")
    drv.close()
    deg = {f"J{i + 1}": round(float(v), 4) for i, v in enumerate(np.degrees(target))}
    deg.update(J7=0.0, J8=0.0, J9=0.0)
    joints0 = rmi.joint_object(q0)
    status = {"Command": "FRC_GetStatus", "ErrorID": 0, "ServoReady": 1, "TPMode": 0,
              "SingleStepMode": 0, "NumberUTool": 1, "NumberUFrame": 0, "Override": 100}
    expected = [
        ("request", {"Command": "FRC_GetStatus"}),
        ("answer", {**status, "RMIMotionStatus": 0, "ProgramStatus": 0, "NextSequenceID": 1}),
        ("request", {"Command": "FRC_Reset"}),
        ("answer", {"Command": "FRC_Reset", "ErrorID": 0}),
        ("request", {"Command": "FRC_Initialize", "GroupMask": 1}),
        ("answer", {"Command": "FRC_Initialize", "ErrorID": 0, "GroupMask": 1}),
        ("request", {"Command": "FRC_GetStatus"}),
        ("answer", {**status, "RMIMotionStatus": 1, "ProgramStatus": 1, "NextSequenceID": 1}),
        ("request", {"Command": "FRC_ReadJointAngles", "Group": 1}),
        ("answer", {"Command": "FRC_ReadJointAngles", "ErrorID": 0, "JointAngle": joints0,
                    "Group": 1}),
        ("request", {"Instruction": "FRC_JointMotionJRep", "SequenceID": 1, "JointAngle": deg,
                     "SpeedType": "Percent", "Speed": 34, "TermType": "FINE", "TermValue": 0}),
        ("answer", {"Instruction": "FRC_JointMotionJRep", "ErrorID": 0, "SequenceID": 1}),
        *[("request", {"Command": "FRC_ReadJointAngles", "Group": 1}),
          ("answer", {"Command": "FRC_ReadJointAngles", "ErrorID": 0, "JointAngle": deg,
                      "Group": 1})] * 2,  # the driver's check at the target, then the role's
        ("request", {"Command": "FRC_ReadCartesianPosition", "Group": 1}),
        ("answer", {"Command": "FRC_ReadCartesianPosition", "ErrorID": 0,
                    **fake._cartesian(), "Group": 1}),
        ("request", {"Communication": "FRC_Disconnect"}),
        ("answer", {"Communication": "FRC_Disconnect", "ErrorID": 0}),
    ]
    got = [(d, {k: v for k, v in p.items() if k != "TimeTag"}) for d, p in fake.transcript]
    assert got == expected
    # the next motion after a new session starts again at sequence 1
    drv.connect()
    drv.move_joints(q0, 0.5, 1.0)
    assert [p["SequenceID"] for d, p in fake.transcript if d == "request"
            and p.get("Instruction")] == [1, 1]


def test_controller_errors_carry_the_rmit_text(fanuc):
    fake, drv, _ = fanuc
    fake.tp_enabled = True
    with pytest.raises(DeviceFault, match=r"FRC_Initialize refused: RMIT-008 Teach Pendant is "
                       r"Enabled \(ErrorID 2556936\)"):
        drv.connect()
    fake.tp_enabled = False
    drv.connect()
    fake.errors["FRC_ReadJointAngles"] = rmi.rmit(7)
    with pytest.raises(DeviceFault, match="RMIT-007 Controller Servo is Off"):
        drv.read_joints()
    drv.read_joints()  # once only
    fake.errors["FRC_JointMotionJRep"] = rmi.rmit(36)
    q = drv.read_joints().value
    with pytest.raises(DeviceFault, match="FRC_JointMotionJRep refused: RMIT-036"):
        drv.move_joints(q, 0.5, 1.0)
    drv.move_joints(q, 0.5, 1.0)  # the refused instruction consumed no sequence number
    with pytest.raises(ValueError, match="limits"):
        fake.world.move(np.radians([0, 0, 500, 0, 0, 0]))


def test_wrong_sequence_and_second_client_refused(fanuc):
    fake, drv, _ = fanuc
    drv.connect()
    drv._seq = 5  # as if instructions of another client had been counted
    q = drv.read_joints().value
    with pytest.raises(DeviceFault, match="RMIT-029 Invalid sequence ID number"):
        drv.move_joints(q, 0.5, 1.0)
    other = FanucRMIRobot(fake.url, timeout=1.0)
    with pytest.raises(DeviceFault, match="RMIT-026 Robot is Already Connected"):
        other.connect()


def test_dropped_connection_and_late_answers(fanuc):
    fake, drv, world = fanuc
    drv.connect()
    world.faults.inject("fanuc-rmi", "disconnect")
    with pytest.raises(ConnectionFailed, match="closed the connection"):
        drv.read_joints()
    drv.read_joints()  # a new session (handshake again), initialized again
    world.faults.inject("fanuc-rmi", "drop")
    with pytest.raises(DeviceTimeout, match="no answer within 0.5 s"):
        drv.read_joints()
    drv.read_joints()
    world.faults.inject("fanuc-rmi", "late")  # the previous answer is sent again first
    drv.read_joints()  # same command: a late ReadJointAngles is indistinguishable...
    world.faults.inject("fanuc-rmi", "late")
    with pytest.raises(ProtocolError, match="late packet"):
        drv.command("FRC_GetStatus")  # ...but not a late answer to another command
    assert drv.command("FRC_GetStatus")["RMIMotionStatus"] == 1
    world.faults.inject("fanuc-rmi", "garbage")
    with pytest.raises(ProtocolError):
        drv.read_joints()
    drv.read_joints()


def test_motion_timeout_aborts(fanuc):
    fake, drv, world = fanuc
    drv.motion_timeout = 0.2
    drv.connect()
    q = drv.read_joints().value
    world.faults.inject("fanuc-rmi", "drop")  # the motion's answer never comes
    with pytest.raises(DeviceTimeout, match="stopped"):
        drv.move_joints(q + np.radians([1, 0, 0, 0, 0, 0]), 0.5, 1.0)
    assert any(p.get("Command") == "FRC_Abort" for d, p in fake.transcript if d == "request")


def test_system_fault_and_terminate_packets():
    server = socket.create_server(("127.0.0.1", 0))
    port = server.getsockname()[1]
    session = socket.create_server(("127.0.0.1", 0))

    import threading

    def controller(packets):
        conn, _ = server.accept()
        conn.recv(100)
        conn.sendall(rmi.encode({"Communication": "FRC_Connect", "ErrorID": 0,
                                 "PortNumber": session.getsockname()[1]}))
        conn.close()
        conn, _ = session.accept()
        conn.recv(100)  # GetStatus
        conn.sendall(rmi.encode({"Command": "FRC_GetStatus", "ErrorID": 0,
                                 "RMIMotionStatus": 0}))
        conn.recv(100)  # Initialize
        conn.sendall(packets)
        conn.close()

    for packets, error, text in (
        (rmi.encode({"Communication": "FRC_SystemFault", "SequenceID": 3}), DeviceFault,
         "system fault during instruction 3"),
        (rmi.encode({"Communication": "FRC_Terminate"}), ConnectionFailed, "FRC_Terminate"),
    ):
        t = threading.Thread(target=controller, args=(packets,), daemon=True)
        t.start()
        with pytest.raises(error, match=text):
            FanucRMIRobot(f"rmi://127.0.0.1:{port}", timeout=1.0).connect()
        t.join(2)
    server.close()
    session.close()


def test_standard_rmi_client_library_on_the_fake(fanuc, tmp_path, capsys):
    fanuc_rmi = pytest.importorskip("fanuc_rmi", reason="needs the fanuc-rmi package "
                                    "(pip install fanuc-rmi)")
    fake, _, world = fanuc
    # the library reads the session port from a key "Port" (the manual's is "PortNumber")
    # and otherwise uses its main_port argument: pass the one the fake announces
    client = fanuc_rmi.RobotClient(host="127.0.0.1", startup_port=fake.port,
                                   main_port=fake.session.port, attempts=1,
                                   startup_pause=0.0, socket_timeout=5, reader_timeout=5)
    client.connect()
    client.initialize(uframe=0, utool=1)
    before = client.read_joint_coordinates(output_path=str(tmp_path / "j.jsonl"))
    assert before["ErrorID"] == 0
    q = np.degrees(world.joint_angles())
    np.testing.assert_allclose([before["JointAngle"][f"J{i}"] for i in range(1, 7)], q,
                               atol=1e-4)
    target = {f"J{i + 1}": float(v) + 1.0 for i, v in enumerate(q)}
    client.joint_absolute(target, speed_percentage=40, sequence_id=1)
    np.testing.assert_allclose(np.degrees(world.joint_angles()), q + 1.0, atol=1e-4)
    cart = client.read_cartesian_coordinates(output_path=str(tmp_path / "c.jsonl"))
    # the joints on the wire are FANUC's (J3 to the horizontal): through the ROS-Industrial
    # URDF's chain (J3_urdf = J3 + J2) they give the position the fake reports
    after = client.read_joint_coordinates(output_path=str(tmp_path / "j.jsonl"))
    q_wire = np.radians([after["JointAngle"][f"J{i}"] for i in range(1, 7)])
    ref = urdf_tool0(R2000IC_URDF, fanuc_urdf_angles(q_wire))
    ref[2, 3] -= 0.670  # the URDF's base_link-base joint: FANUC's world frame
    np.testing.assert_allclose([cart["Position"][k] for k in "XYZ"], ref[:3, 3] * 1e3,
                               atol=2e-3)
    assert client.abort()["ErrorID"] == 0
    assert fake.transcript[-2] == ("request", {"Command": "FRC_Abort"})
    client.close()
    assert fake.transcript[-1] == ("answer", {"Communication": "FRC_Disconnect", "ErrorID": 0})
    capsys.readouterr()  # the library prints every answer
