"""One robot, one acquisition: a hardware run refuses while another process of this machine
holds the robot's claim, before anything is connected; the claim dies with its holder."""

from __future__ import annotations

import shutil
import socket
import subprocess
import sys
import threading
import uuid

import pytest

from analysis.errors import InputError
from campaign.acquire.robot_claim import RobotBusy, hold

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"),
                                reason="abstract Unix sockets are Linux's")

HOLDER = """
import sys
from campaign.acquire.robot_claim import hold
claim = hold(sys.argv[1])
print("held", flush=True)
sys.stdin.readline()
"""


class Listener:
    """A loopback TCP listener that counts the connections it accepts."""

    def __init__(self) -> None:
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.accepted = 0
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.accepted += 1
            conn.close()

    def close(self) -> None:
        self.sock.close()


def _holder(robot: str) -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, "-c", HOLDER, robot], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    return proc


def _release(proc: subprocess.Popen) -> None:
    proc.stdin.close()
    proc.wait(timeout=60)


def test_a_claim_is_exclusive_across_processes_and_ends_with_its_holder():
    robot = f"kuka-kvp socket://127.0.0.1:1 test-{uuid.uuid4().hex}"  # unique per xdist worker
    proc = _holder(robot)
    try:
        with pytest.raises(RobotBusy, match="already running on this robot"):
            hold(robot)
        other = hold(robot + " another")  # another robot is free
        other.release()
    finally:
        _release(proc)
    claim = hold(robot)  # the kernel released the holder's name when it ended
    with pytest.raises(RobotBusy):
        hold(robot)
    claim.release()
    hold(robot).release()


def test_a_hardware_run_refuses_a_claimed_robot_before_connecting(kr240_plan, tmp_path):
    from campaign.jobs.acquire import AcquireJobOptions, run

    listener = Listener()
    plan = tmp_path / "plan"
    shutil.copytree(kr240_plan, plan)
    protocol = plan / "protocol.toml"
    address = f"socket://127.0.0.1:{listener.port}"
    protocol.write_text(protocol.read_text().replace("socket://192.168.1.20:7000", address))
    proc = _holder(f"kuka-kvp {address}")
    try:
        with pytest.raises(InputError, match="already running on this robot") as err:
            run(AcquireJobOptions(plan=str(plan), out=str(tmp_path / "run"), fake=False,
                                  assume_yes=True), say=lambda s: None)
        assert err.value.where == "robot"
    finally:
        _release(proc)
        listener.close()
    assert listener.accepted == 0
    assert not (tmp_path / "run").exists()
