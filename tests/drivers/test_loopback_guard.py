"""Loopback-only mode: drivers refuse devices off this machine before any traffic."""

from __future__ import annotations

import socket
import subprocess
import sys
import threading

import pytest

from drivers.errors import ConnectionFailed
from drivers.loopback_guard import (
    ENV,
    check_address,
    child_environment,
    is_loopback_host,
    loopback_only,
    loopback_only_mode,
)
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
        seen["mode"] = loopback_only()
        seen["child"] = child_environment().get(ENV)
        return Outcome()

    monkeypatch.delenv(ENV)
    monkeypatch.setattr(session, "acquire", fake_session)
    acquire.run(acquire.AcquireJobOptions(plan=tmp_path, out=tmp_path / "run", fake=fake,
                                          assume_yes=True), say=lambda s: None)
    assert seen["mode"] is fake
    assert seen["child"] == ("1" if fake else None)  # the processes the run starts
    assert ENV not in os.environ  # the mode never went into the process's environment
    assert not loopback_only()  # restored after the run


def _in_threads(*targets, timeout: float = 30.0) -> None:
    """Run the targets in threads of their own, at once; re-raise the first failure."""
    errors: list[BaseException] = []

    def wrapped(fn):
        try:
            fn()
        except BaseException as err:  # noqa: BLE001 (re-raised in the test's thread)
            errors.append(err)

    threads = [threading.Thread(target=wrapped, args=(t,)) for t in targets]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout)
    assert not any(t.is_alive() for t in threads), "a thread did not finish"
    if errors:
        raise errors[0]


def test_concurrent_jobs_in_threads_each_see_their_own_mode(monkeypatch):
    """A fake run's mode neither leaks to a hardware job running beside it in another
    thread of the same process, nor is it lifted when another fake run ends first."""
    monkeypatch.delenv(ENV)  # the operator's GUI server: no process-wide mode
    step = threading.Barrier(3, timeout=10)
    seen: dict[str, list] = {"fake": [], "other_fake": [], "hardware": []}

    def fake_run():  # ends first
        with loopback_only_mode(True):
            step.wait()  # 1: all three jobs inside their blocks
            seen["fake"].append(loopback_only())
            with pytest.raises(ConnectionFailed, match="192.168.1.1 is not a loopback"):
                check_address("udp://192.168.1.1:49152")
            step.wait()  # 2: every job has looked
        step.wait()  # 3: this fake run has ended

    def other_fake_run():  # still running when the first one ends
        with loopback_only_mode(True):
            step.wait()
            seen["other_fake"].append(loopback_only())
            step.wait()
            step.wait()
            seen["other_fake"].append(loopback_only())
            with pytest.raises(ConnectionFailed):
                check_address("tcp://192.168.1.2:7000")

    def hardware_run():  # the guard off
        with loopback_only_mode(False):
            step.wait()
            seen["hardware"].append(loopback_only())
            check_address("udp://192.168.1.1:49152")  # its own hardware: not refused
            step.wait()
            step.wait()
            seen["hardware"].append(loopback_only())

    _in_threads(fake_run, other_fake_run, hardware_run)
    assert seen == {"fake": [True], "other_fake": [True, True], "hardware": [False, False]}
    assert not loopback_only() and ENV not in __import__("os").environ


def test_a_job_cannot_lift_the_process_wide_mode():
    # the suite's mode (tests/conftest.py): a job without the guard is still held to it
    with loopback_only_mode(False):
        assert loopback_only()
        with pytest.raises(ConnectionFailed):
            check_address("ur://192.168.1.20")


def test_a_process_started_in_a_fake_run_inherits_its_mode(monkeypatch):
    monkeypatch.delenv(ENV)
    assert ENV not in child_environment()
    code = ("from drivers.registry import open_driver\n"
            "try:\n    open_driver('ati-netft', 'udp://192.168.1.1:49152').connect()\n"
            "except Exception as e:\n    print(type(e).__name__, e)\n")
    with loopback_only_mode():
        env = child_environment()
    assert env[ENV] == "1"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, env=env).stdout
    assert out.startswith("ConnectionFailed") and "192.168.1.1" in out, out


def test_two_acquisition_jobs_in_threads_fake_and_hardware(monkeypatch, tmp_path):
    """The GUI's thread-mode jobs: a fake acquisition and a hardware one run at once in
    two threads of one process; inside its session each sees its own mode, and the fake
    one's drivers refuse 192.168.x."""
    import campaign.acquire.session as session
    from campaign.jobs import acquire

    both_inside = threading.Barrier(2, timeout=10)
    seen, refused = {}, {}

    class Outcome:
        status, reason, run_dir, ok, failed, exported = "complete", "", tmp_path, 0, 0, None

    def fake_session(plan, out, resume, opts, *a, **k):
        both_inside.wait()
        seen[opts.fake] = loopback_only()
        if opts.fake:
            with pytest.raises(ConnectionFailed, match="not a loopback address"):
                open_driver("ati-netft", "udp://192.168.1.1:49152").connect()
            refused[opts.fake] = True
        both_inside.wait()
        return Outcome()

    monkeypatch.delenv(ENV)
    monkeypatch.setattr(session, "acquire", fake_session)

    def job(fake):
        return lambda: acquire.run(acquire.AcquireJobOptions(
            plan=tmp_path, out=tmp_path / f"run-{fake}", fake=fake, assume_yes=True),
            say=lambda s: None)

    _in_threads(job(True), job(False))
    assert seen == {True: True, False: False} and refused == {True: True}
