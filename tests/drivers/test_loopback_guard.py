"""Loopback-only mode: drivers refuse devices off this machine before any traffic."""

from __future__ import annotations

import socket
import subprocess
import sys

import pytest

from drivers.errors import ConnectionFailed
from drivers.loopback_guard import ENV, check_address, is_loopback_host, loopback_only_mode
from drivers.registry import open_driver


@pytest.mark.parametrize("host, loop", [
    ("127.0.0.1", True), ("127.3.2.1", True), ("::1", True), ("[::1]", True),
    ("localhost", True), ("LOCALHOST", True), ("192.168.1.1", False), ("10.0.0.1", False),
    ("::ffff:192.168.1.1", False), ("example.com", False), ("127.0.0.1.nip.io", False),
    ("0.0.0.0", False), ("", False)])
def test_loopback_hosts(host, loop):
    assert is_loopback_host(host) is loop


def test_the_suite_runs_in_loopback_only_mode():
    import os

    assert os.environ.get(ENV) == "1"  # set by tests/conftest.py for every process started


@pytest.mark.parametrize("driver, address", [
    ("ati-netft", "udp://192.168.1.1:49152"), ("emscon", "socket://192.168.1.10:700"),
    ("geocom", "socket://10.1.2.3:1212"), ("ur", "ur://192.168.1.20"),
    ("kuka-kvp", "socket://192.168.1.30:7000"), ("fanuc-rmi", "rmi://192.168.1.40"),
    ("abb-rws", "rws://Default%20User:robotics@192.168.125.1"),
    ("ati-netcan", "can://can0?interface=socketcand&host=192.168.1.50&port=29536")])
def test_a_driver_off_loopback_is_refused_before_any_socket(driver, address, monkeypatch):
    opened = []
    real = socket.socket

    def spy(*a, **k):
        opened.append(a)
        return real(*a, **k)

    monkeypatch.setattr(socket, "socket", spy)
    monkeypatch.setattr(socket, "create_connection", lambda *a, **k: opened.append(a))
    try:
        drv = open_driver(driver, address)
    except Exception as err:  # noqa: BLE001 (a driver whose library is missing here)
        pytest.skip(f"{driver}: {err}")
    with pytest.raises(ConnectionFailed, match="not a loopback address"):
        drv.connect()
    assert opened == [] and not drv.connected


def test_loopback_addresses_and_local_devices_pass():
    for text in ("udp://127.0.0.1:49152", "socket://localhost:700", "ur://127.0.0.5",
                 "tcp://[::1]:5000", "/dev/ttyUSB0?baud=19200", "can://vcan0", "manual://",
                 "not an address"):
        check_address(text)


def test_mode_off_checks_nothing_and_the_block_restores(monkeypatch):
    monkeypatch.delenv(ENV)
    check_address("udp://192.168.1.1:49152")  # the operator's own hardware run
    with loopback_only_mode():
        with pytest.raises(ConnectionFailed):
            check_address("udp://192.168.1.1:49152")
    check_address("udp://192.168.1.1:49152")
    with loopback_only_mode(False):
        check_address("udp://192.168.1.1:49152")
    monkeypatch.setenv(ENV, "0")
    check_address("udp://192.168.1.1:49152")


def test_a_started_process_inherits_the_mode():
    code = ("from drivers.registry import open_driver\n"
            "try:\n    open_driver('ati-netft', 'udp://192.168.1.1:49152').connect()\n"
            "except Exception as e:\n    print(type(e).__name__, e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60).stdout
    assert out.startswith("ConnectionFailed") and ENV in out, out


@pytest.mark.parametrize("fake", [True, False])
def test_an_acquisition_on_the_simulated_lab_runs_in_loopback_only_mode(fake, monkeypatch,
                                                                        tmp_path):
    import os

    import campaign.acquire.session as session
    from campaign.jobs import acquire

    seen = {}

    class Outcome:
        status, reason, run_dir, ok, failed, exported = "complete", "", tmp_path, 0, 0, None

    def fake_session(*a, **k):
        seen["mode"] = os.environ.get(ENV)
        return Outcome()

    monkeypatch.delenv(ENV)
    monkeypatch.setattr(session, "acquire", fake_session)
    acquire.run(acquire.AcquireJobOptions(plan=tmp_path, out=tmp_path / "run", fake=fake,
                                          assume_yes=True), say=lambda s: None)
    assert seen["mode"] == ("1" if fake else None)
    assert ENV not in os.environ  # restored after the run
