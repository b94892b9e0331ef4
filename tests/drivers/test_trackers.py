"""Tracker drivers against their fakes over TCP: points, 6-DoF probe, reflector fit, faults."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.emscon import EmsconTracker
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.frames import matrix_to_rotvec
from drivers.geocom import GeoComTracker
from drivers.sim.fake_emscon import FakeEmscon
from drivers.sim.fake_geocom import FakeGeoCom, FakeGeoComSerial

pytestmark = pytest.mark.timeout(60)

KINDS = {"emscon-int32": (lambda w: FakeEmscon(w, header="int32"), EmsconTracker),
         "emscon-int64": (lambda w: FakeEmscon(w, header="int64"), EmsconTracker),
         "geocom": (FakeGeoCom, GeoComTracker),
         "geocom-serial": (FakeGeoComSerial, GeoComTracker)}


@pytest.fixture(params=sorted(KINDS))
def tracker(request, world):
    make_fake, driver = KINDS[request.param]
    fake = make_fake(world)
    fake.start()
    reflectors = {k: v for k, v in world.settings.reflectors.items() if k != "P"}
    drv = driver(fake.url, reflectors=reflectors, aim=world.aim, timeout=1.0)
    drv.connect()
    yield fake, drv
    drv.close()
    fake.stop()


def test_point_is_the_reflector_in_the_tracker_frame(tracker, world):
    _fake, drv = tracker
    p = drv.measure_point("P")
    truth = (world.base_in_tracker @ world.true_tool_pose())[:3, 3]
    assert np.linalg.norm(p.value - truth) < 6 * world.settings.tracker_noise
    assert p.unit == "m" and p.frame == "tracker" and p.target == "P"


def test_reflector_fit_gives_the_tool_pose_and_a_small_residual(tracker, world):
    _fake, drv = tracker
    pose = drv.measure_pose()
    truth = world.base_in_tracker @ world.true_tool_pose()
    noise = world.settings.tracker_noise
    assert np.linalg.norm(pose.value[:3, 3] - truth[:3, 3]) < 8 * noise
    angle = np.linalg.norm(matrix_to_rotvec(pose.value[:3, :3] @ truth[:3, :3].T))
    assert angle < 8 * noise / 0.1  # reflectors about 0.1 m apart
    assert 0 < pose.residual < 4 * noise


def test_deflection_under_load_is_seen_by_the_tracker(tracker, world, settle):
    _fake, drv = tracker
    before = drv.measure_point("P").value
    world.apply_load(np.array([0.0, 0.0, -2000.0, 0, 0, 0]))
    settle(world)
    after = drv.measure_point("P").value
    expected = world.base_in_tracker[:3, :3] @ (world.true_tool_pose()[:3, 3]
                                                - world.nominal_tool_pose()[:3, 3])
    assert np.linalg.norm(expected) > 1e-3  # millimetres under 2 kN on a KR240
    assert np.linalg.norm((after - before) - expected) < 8 * world.settings.tracker_noise


def test_beam_lost_is_a_fault_then_measuring_resumes(tracker, world):
    fake, drv = tracker
    world.faults.inject(fake.device, "beam_lost", 1)
    with pytest.raises(DeviceFault, match="beam lost"):
        drv.measure_point("P")
    assert np.all(np.isfinite(drv.measure_point("P").value))


def test_no_answer_times_out_and_the_next_answer_is_not_stale(tracker, world):
    fake, drv = tracker
    world.faults.inject(fake.device, "drop", 1)
    with pytest.raises(DeviceTimeout):
        drv.measure_point("P")
    world.aim("R1")
    p = drv.measure_point("R1").value
    truth = (world.base_in_tracker @ world.true_tool_pose() @ np.append(
        world.reflectors["R1"], 1))[:3]
    assert np.linalg.norm(p - truth) < 6 * world.settings.tracker_noise


def test_garbage_is_a_protocol_error_or_timeout(tracker, world):
    fake, drv = tracker
    world.faults.inject(fake.device, "garbage", 1)
    with pytest.raises((ProtocolError, DeviceTimeout)):
        drv.measure_point("P")
    assert np.all(np.isfinite(drv.measure_point("P").value))


def test_disconnect_is_a_connection_error(tracker, world):
    fake, drv = tracker
    world.faults.inject(fake.device, "disconnect", 1)
    # a serial line cannot hang up: the instrument just falls silent
    expected = DeviceTimeout if isinstance(fake, FakeGeoComSerial) else ConnectionFailed
    with pytest.raises(expected):
        drv.measure_point("P")


def test_six_dof_probe(world):
    fake = FakeEmscon(world, mode="6dof")
    fake.start()
    try:
        with EmsconTracker(fake.url) as drv:
            pose = drv.measure_pose()
        truth = world.base_in_tracker @ world.true_tool_pose()
        assert np.linalg.norm(pose.value[:3, 3] - truth[:3, 3]) < 8 * world.settings.tracker_noise
        assert np.linalg.norm(matrix_to_rotvec(pose.value[:3, :3] @ truth[:3, :3].T)) < \
            8 * world.settings.tracker_angle_noise
    finally:
        fake.stop()


@pytest.mark.parametrize("mode", ["point", "6dof"])
def test_emscon_skips_position_packets_before_the_result(world, mode):
    fake = FakeEmscon(world, mode=mode, position_stream=True)
    fake.start()
    try:
        with EmsconTracker(fake.url, timeout=1.0) as drv:
            truth = world.base_in_tracker @ world.true_tool_pose()
            for _ in range(3):  # the skipped packet must not shift the next answer
                value = (drv.measure_pose().value[:3, 3] if mode == "6dof"
                         else drv.measure_point("P").value)
                assert np.linalg.norm(value - truth[:3, 3]) < 8 * world.settings.tracker_noise
    finally:
        fake.stop()


def _scripted_emscon(answer: bytes, repeat: bool = False) -> str:
    """A one-client server answering a command with an OK acknowledgement + ``answer``.

    With ``repeat`` it keeps sending ``answer`` every 10 ms (an endless position stream).
    """
    import socket
    import threading

    from drivers import emscon

    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)

    def serve():
        conn, _ = srv.accept()
        with conn:
            while True:
                head = conn.recv(12)
                if len(head) < 12:
                    return
                ack = emscon.encode_packet(emscon.DT_COMMAND, emscon.REPLY_BODY.pack(49, 0))
                conn.sendall(ack + answer)
                while repeat:
                    try:
                        conn.sendall(answer)
                    except OSError:
                        return
                    time.sleep(0.01)

    threading.Thread(target=serve, daemon=True).start()
    return f"socket://127.0.0.1:{srv.getsockname()[1]}"


def test_emscon_refuses_6d_errors_extended_statistics_and_endless_streams():
    from drivers import emscon

    q = np.array([1.0, 0.0, 0.0, 0.0])
    bad_6d = emscon.encode_packet(emscon.DT_PROBE_STATIONARY, emscon.encode_probe(
        0, np.zeros(3), q, rotation_status=emscon.ROT_STATUS_VALID | emscon.ROT_STATUS_ERROR))
    with EmsconTracker(_scripted_emscon(bad_6d), timeout=1.0) as drv, \
            pytest.raises(DeviceFault, match="rotation status"):
        drv.measure_pose()
    single2 = emscon.encode_packet(emscon.DT_SINGLE2, bytes(12 + 23 * 8))
    with EmsconTracker(_scripted_emscon(single2), timeout=1.0) as drv, \
            pytest.raises(ProtocolError, match="extended"):
        drv.measure_point("P")
    stream = emscon.encode_packet(emscon.DT_PROBE_POS, emscon.encode_probe_position(
        np.zeros(3), q))
    t0 = time.monotonic()
    with EmsconTracker(_scripted_emscon(stream, repeat=True), timeout=0.3) as drv, \
            pytest.raises(DeviceTimeout, match="no measurement result"):
        drv.measure_pose()
    assert time.monotonic() - t0 < 2.0


def test_wrong_header_layout_is_detected(world):
    fake = FakeEmscon(world, header="int64")
    fake.start()
    try:
        url = fake.url.replace("header=int64", "header=int32")
        with EmsconTracker(url, timeout=1.0) as drv, \
                pytest.raises((ProtocolError, DeviceTimeout, ConnectionFailed)):
            drv.measure_point("P")
    finally:
        fake.stop()


def test_fewer_than_three_reflectors_is_refused():
    with pytest.raises(ValueError, match="three"):
        GeoComTracker("socket://127.0.0.1:1", reflectors={"a": [0, 0, 0], "b": [1, 0, 0]})


def test_geocom_ignores_a_late_reply_to_an_earlier_request(world):
    fake = FakeGeoCom(world)
    fake.start()
    try:
        with GeoComTracker(fake.url, timeout=1.0) as drv:
            world.faults.inject(fake.device, "late", 1)
            with pytest.raises(DeviceTimeout):
                drv.measure_point("P")  # its answer comes 1.5 s later
            world.aim("R2")
            truth = (world.base_in_tracker @ world.true_tool_pose() @ np.append(
                world.reflectors["R2"], 1))[:3]
            t_end = time.monotonic() + 1.0
            while time.monotonic() < t_end:  # the late line for "P" arrives meanwhile
                p = drv.measure_point("R2").value
                assert np.linalg.norm(p - truth) < 6 * world.settings.tracker_noise
                time.sleep(0.01)
    finally:
        fake.stop()


def test_geocom_never_reuses_the_id_of_a_request_whose_late_reply_may_come(scripted_geocom):
    """With ids 1..7 in turn, the 14th call after a timed-out TMC_GetCoordinate is again a
    TMC_GetCoordinate under the same id: its late reply, arriving just then, must not be
    taken for that call's (the race the fake's 1.5 s "late" fault hits only by chance)."""
    from drivers import geocom

    state = {"calls": 0, "held": None, "trids_after": []}

    def reply(rpc, trid):
        state["calls"] += 1
        if rpc == geocom.RPC_GET_COORDINATE and state["held"] is None:
            state["held"] = (state["calls"],
                             geocom.encode_reply(0, "9.0", "9.0", "9.0", trid=trid))
            return b""  # no answer now: the driver times out
        good = geocom.encode_reply(0, "1.0", "2.0", "3.0", trid=trid)
        if state["held"] is not None:
            state["trids_after"].append(trid)
            if state["calls"] == state["held"][0] + 14:
                return state["held"][1] + good  # the late reply comes first
        return good

    with GeoComTracker(scripted_geocom(reply), timeout=0.3) as drv:
        with pytest.raises(DeviceTimeout):
            drv.measure_point()
        for _ in range(12):  # 24 calls: past the late reply, through every id again
            np.testing.assert_allclose(drv.measure_point().value, [1.0, 2.0, 3.0])
        assert drv.stale_replies == 1
    late_id = int(state["held"][1].split(b",")[2].split(b":")[0])
    before, after = state["trids_after"][:14], state["trids_after"][14:]
    assert late_id not in before  # not reused while its reply may come
    assert set(after) == set(range(1, 8))  # and free again once it came


def test_geocom_refuses_when_every_id_may_still_get_a_late_reply(scripted_geocom):
    from drivers import geocom

    asked = []

    def reply(rpc, trid):
        asked.append(trid)
        return b""  # never answers

    with GeoComTracker(scripted_geocom(reply), timeout=0.05) as drv:
        for _ in range(geocom.TRIDS):
            with pytest.raises(DeviceTimeout, match="no reply"):
                drv.measure_point()
        with pytest.raises(DeviceTimeout, match="7 requests unanswered"):
            drv.measure_point()
    time.sleep(0.1)
    assert sorted(asked) == list(range(1, 8))  # each id once; the 8th request never sent


def test_geocom_skips_replies_with_another_transaction_id(scripted_geocom):
    from drivers import geocom

    def reply(rpc, trid):
        stale = geocom.encode_reply(0, "9.0", "9.0", "9.0", trid=trid % 7 + 1)
        good = geocom.encode_reply(0, "1.0", "2.0", "3.0", trid=trid)
        return stale + good if rpc == geocom.RPC_GET_COORDINATE else good

    with GeoComTracker(scripted_geocom(reply), timeout=1.0) as drv:
        np.testing.assert_allclose(drv.measure_point().value, [1.0, 2.0, 3.0])
        assert drv.stale_replies == 1
