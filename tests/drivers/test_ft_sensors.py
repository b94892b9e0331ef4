"""Force/torque drivers against their fakes over the real transports (UDP+HTTP, pty, CAN)."""

from __future__ import annotations

import time

import numpy as np
import pytest

from drivers.ati_netcan import NetCANSensor
from drivers.ati_netft import NetFTSensor
from drivers.errors import DeviceFault, DeviceTimeout, ProtocolError, SafetyRefusal
from drivers.frames import wrench_to_base
from drivers.robotiq_ft300 import FT300Sensor
from drivers.safety import check_force
from drivers.sim.fake_ft300 import FakeFT300
from drivers.sim.fake_netcan import FakeNetCAN
from drivers.sim.fake_netft import FakeNetFT

pytestmark = pytest.mark.timeout(60)

# (fake, driver, resolution of one reading: N, N m)
KINDS = {
    "netft": (FakeNetFT, NetFTSensor, (1e-5, 1e-5)),
    "ft300": (FakeFT300, FT300Sensor, (0.01, 0.001)),
    "netcan": (lambda w: FakeNetCAN(w, interface="virtual"), NetCANSensor, (0.2, 0.01)),
}


@pytest.fixture(params=sorted(KINDS))
def sensor(request, world):
    make_fake, driver, resolution = KINDS[request.param]
    fake = make_fake(world)
    fake.start()
    drv = driver(fake.url)
    drv.connect()
    yield request.param, fake, drv, np.array(resolution * 1).repeat(3)
    drv.close()
    fake.stop()


def test_loaded_wrench_in_base_frame_matches_the_applied_load(sensor, world, settle):
    name, _fake, drv, resolution = sensor
    drv.tare(30)
    load = np.array([60.0, -40.0, -200.0, 0.0, 0.0, 0.0])  # inside the FT 300 range
    world.apply_load(load)
    settle(world)
    n = 60
    w = drv.read_wrench(n)
    T = world.true_tool_pose()
    in_base = wrench_to_base(w.value, T, world.sensor_mount, T[:3, 3])
    sigma = np.array([world.settings.force_noise] * 3 + [world.settings.torque_noise] * 3)
    # tare noise + averaging noise (5 sigma) + quantisation of one count
    tol = 5 * sigma * np.sqrt(1 / n + 1 / 30) + resolution
    assert np.all(np.abs(in_base - load) < tol), (name, in_base - load, tol)
    # the spread reported is the per-sample noise, not zero and not huge
    assert np.all(w.spread > 0.5 * sigma) and np.all(w.spread < 2 * sigma + resolution)
    assert w.samples == n and w.frame == "sensor"


def test_safety_stop_on_excess_force(sensor, world, settle):
    _name, _fake, drv, _res = sensor
    world.apply_load(np.array([0.0, 0.0, -250.0, 0, 0, 0]))
    settle(world)
    with pytest.raises(SafetyRefusal, match="above the limit"):
        check_force(drv.read_wrench(10).value, max_force=150.0)


def test_frozen_sensor_is_a_fault(sensor, world):
    _name, fake, drv, _res = sensor
    world.faults.inject(fake.device, "frozen", -1)
    with pytest.raises(DeviceFault, match="frozen"):
        drv.read_wrench(20)


def test_silent_device_times_out_quickly(sensor, world):
    _name, fake, drv, _res = sensor
    world.faults.inject(fake.device, "disconnect", 1)
    t0 = time.monotonic()
    with pytest.raises(DeviceTimeout):
        drv.read_wrench(20)
    assert time.monotonic() - t0 < 3 * drv.timeout + 1


def test_netft_skips_dropped_late_and_garbage_datagrams(world):
    fake = FakeNetFT(world)
    fake.start()
    try:
        with NetFTSensor(fake.url) as drv:
            drv.read_wrench(5)
            for fault in ("drop", "late", "garbage"):
                world.faults.inject(fake.device, fault, 5)
            w = drv.read_wrench(100)
            assert np.all(np.abs(w.value[:3]) < 1.0)  # still the unloaded truth
            assert drv.dropped >= 5 and drv.discarded >= 10
            world.faults.inject(fake.device, "garbage", -1)
            with pytest.raises(ProtocolError, match="malformed|multiple of 36"):
                drv.read_wrench(5)
    finally:
        fake.stop()


def test_ft300_resynchronises_after_bad_crc_and_refuses_endless_ones(world):
    fake = FakeFT300(world)
    fake.start()
    try:
        with FT300Sensor(fake.url) as drv:
            world.faults.inject(fake.device, "bad_crc", 3)
            world.faults.inject(fake.device, "garbage", 3)
            w = drv.read_wrench(20)
            assert drv.bad_frames >= 3 and np.all(np.abs(w.value[:3]) < 1.0)
            world.faults.inject(fake.device, "bad_crc", -1)
            with pytest.raises(ProtocolError, match="CRC"):
                drv.read_wrench(5)
    finally:
        fake.stop()


def test_ft300_refuses_a_saturated_reading(world, settle):
    fake = FakeFT300(world)
    fake.start()
    try:
        with FT300Sensor(fake.url) as drv:
            world.apply_load(np.array([0.0, 0.0, -1000.0, 0, 0, 0]))  # beyond +-300 N
            settle(world)
            with pytest.raises(DeviceFault, match="saturated"):
                drv.read_wrench(5)
    finally:
        fake.stop()


def test_netcan_retries_a_dropped_answer_and_rejects_garbage(world):
    fake = FakeNetCAN(world, interface="virtual")
    fake.start()
    try:
        with NetCANSensor(fake.url) as drv:
            world.faults.inject(fake.device, "drop", 1)
            assert np.all(np.abs(drv.read_wrench(5).value[:3]) < 2.0)
            world.faults.inject(fake.device, "garbage", 1)
            with pytest.raises(ProtocolError):
                drv.read_wrench(5)
    finally:
        fake.stop()


def test_netft_calibration_page_unreachable_is_a_connection_error(world):
    fake = FakeNetFT(world)
    url = fake.url.split("?")[0] + "?http_port=1"
    with pytest.raises(ConnectionError):
        NetFTSensor(url, timeout=0.5).connect()
    fake.sock.close()


class ScriptedNetFT:
    """A bare UDP peer playing a Net F/T from a script (no simulated world)."""

    def __init__(self, records, ignore_first_start=False):
        import socket
        import threading

        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))
        self.sock.settimeout(0.002)
        self.records, self.ignore = list(records), ignore_first_start
        self.starts = 0
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()
        self.url = f"udp://127.0.0.1:{self.sock.getsockname()[1]}?cpf=1000&cpt=1000"

    def run(self):
        from drivers import ati_netft

        peer = None
        while not self.stop.is_set():
            try:
                data, addr = self.sock.recvfrom(64)
                if ati_netft.decode_request(data)[0] == ati_netft.CMD_START_REALTIME:
                    self.starts += 1
                    if not (self.ignore and self.starts == 1):
                        peer = addr
            except TimeoutError:
                pass
            if peer is not None and self.records:
                self.sock.sendto(ati_netft.encode_record(self.records.pop(0)), peer)

    def close(self):
        self.stop.set()
        self.thread.join()
        self.sock.close()


def _rec(seq, status=0, counts=(1000, 0, 0, 0, 0, 0)):
    from drivers.ati_netft import RdtRecord

    return RdtRecord(seq, seq, status, counts)


def test_netft_status_word_is_a_fault_and_counts_scale_with_the_override():
    peer = ScriptedNetFT([_rec(1), _rec(2, status=0x80000000)])
    try:
        with NetFTSensor(peer.url, timeout=1.0) as drv:
            np.testing.assert_allclose(drv.read_sample(), [1.0, 0, 0, 0, 0, 0])
            with pytest.raises(DeviceFault, match="0x80000000"):
                drv.read_sample()
    finally:
        peer.close()


def test_netft_resends_start_after_silence_and_accepts_a_restarted_count():
    records = [_rec(100 + i) for i in range(3)] + [_rec(1 + i) for i in range(30)]
    peer = ScriptedNetFT(records, ignore_first_start=True)
    try:
        with NetFTSensor(peer.url, timeout=1.0) as drv:
            drv.read_sample()  # arrives only after the driver re-sent its start request
            assert drv.restarts == 1 and peer.starts >= 2
            for _ in range(12):  # 102 -> 1: a sensor reboot restarts the sequence numbers
                drv.read_sample()
            assert drv.discarded == NetFTSensor.max_bad_datagrams - 1
    finally:
        peer.close()
