"""Read-only checks on real instruments; skipped unless an address is given.

    pytest tests/drivers/test_hardware_devices.py --ft-url udp://192.168.1.1:49152 \
        --tracker-url socket://192.168.0.10:700 --robot-url ur://192.168.0.20

Use ``name:address`` to choose the driver (e.g. ``robotiq-ft300:/dev/ttyUSB0``);
the default driver is guessed from the scheme. Nothing here moves a robot.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.registry import open_driver

pytestmark = [pytest.mark.hardware, pytest.mark.timeout(60)]
DEFAULTS = {"ft": {"udp": "ati-netft", "serial": "robotiq-ft300", "can": "ati-netcan"},
            "tracker": {"tcp": "emscon", "serial": "geocom"},
            "robot": {"ur": "ur", "tcp": "kuka-kvp", "manual": "manual"}}


def _device(request, role):
    from drivers.address import parse_address

    try:
        text = request.config.getoption(f"--{role}-url", default=None)
    except ValueError:
        text = None
    if not text:
        pytest.skip(f"no --{role}-url given")
    name, sep, address = text.partition(":")
    if not sep or "/" in name or name in ("udp", "socket", "tcp", "can", "ur", "serial"):
        name, address = DEFAULTS[role].get(parse_address(text).scheme), text
    if name is None:
        pytest.skip(f"cannot guess a driver for {text}; write name:address")
    return open_driver(name, address)


def test_force_sensor_reads_finite_wrenches(request):
    with _device(request, "ft") as sensor:
        w = sensor.read_wrench(50)
        assert np.all(np.isfinite(w.value)) and np.all(w.spread >= 0)


def test_tracker_measures_a_point(request):
    with _device(request, "tracker") as tracker:
        assert np.all(np.isfinite(tracker.measure_point().value))


def test_robot_reports_joint_angles(request):
    with _device(request, "robot") as robot:
        q = robot.read_joints().value
        assert q.shape == (robot.n_joints,) and np.all(np.abs(q) < 2 * np.pi)
