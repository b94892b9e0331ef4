"""lab: the simulated lab as an object; started by run(), stopped by its with block.

Everything binds 127.0.0.1. The control channel's port can be chosen; its
``addresses`` command lists the same fakes as the object; after the block nothing
listens there any more.
"""

from __future__ import annotations

import socket

import numpy as np
import pytest

from analysis.errors import InputError
from campaign.jobs.lab import LabOptions, run
from campaign.protocol import load_protocol
from campaign.shipped_protocols import shipped_protocol
from drivers.registry import open_driver
from drivers.sim.control import LabClient

pytestmark = pytest.mark.timeout(120)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(1.0)
        return s.connect_ex(("127.0.0.1", port)) == 0


def test_lab_of_a_protocol_on_a_chosen_control_port():
    path = shipped_protocol("kr240-2")
    true_k = load_protocol(path).lab["true_joint_stiffness"]
    port = _free_port()
    with run(LabOptions(protocol=path, seed=7, time_scale=100.0, control_port=port)) as lab:
        assert lab.addresses["control"] == f"tcp://127.0.0.1:{port}"
        assert {"kuka-kvp", "ati-netft", "emscon"} <= set(lab.addresses)
        assert all("127.0.0.1" in url for name, url in lab.addresses.items()
                   if url.startswith(("tcp", "udp", "http")))
        assert lab.settings.seed == 7 and lab.settings.time_scale == 100.0
        np.testing.assert_array_equal(lab.settings.true_joint_stiffness, true_k)
        assert any("1409.8" in line for line in lab.description)  # kN m/rad, Table 2
        with LabClient(f"tcp://127.0.0.1:{port}") as client:
            assert client.call("addresses")["addresses"] == lab.addresses
        with open_driver("kuka-kvp", lab.addresses["kuka-kvp"]) as robot:
            q = robot.read_joints().value
            assert q.shape == (6,) and np.all(np.isfinite(q))
    assert not _listening(port)


def test_lab_options_refused_naming_the_option():
    path = shipped_protocol("kr240-2")
    with pytest.raises(InputError, match=r"--robot: the protocol names the robot"):
        run(LabOptions(protocol=path, robot="ur10e"))
    with pytest.raises(InputError, match=r"--control-port: expected a port number"):
        run(LabOptions(control_port=70000))
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(InputError, match=rf"--control-port: port {port} on 127.0.0.1"):
            run(LabOptions(instruments=["geocom"], control_port=port))
    with pytest.raises(InputError, match="unknown instruments"):
        run(LabOptions(instruments=["laser-cannon"]))
    with pytest.raises(InputError, match=r"--port: ati-netft cannot take a fixed port"):
        run(LabOptions(ports={"ati-netft": _free_port()}))
    with pytest.raises(InputError, match=r"--port: geocom: expected a port number"):
        run(LabOptions(ports={"geocom": 0}))
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(InputError, match=r"--port: a fake cannot listen on its port"):
            run(LabOptions(instruments=["geocom"], ports={"geocom": port}))


def test_fixed_ports_of_fakes():
    """geocom and the KUKA robot's fake on the ports asked for; a real client reads them."""
    ports = {"geocom": _free_port(), "kuka-kvp": _free_port()}
    with run(LabOptions(instruments=["geocom", "robot"], ports=ports)) as lab:
        assert lab.addresses["geocom"] == f"socket://127.0.0.1:{ports['geocom']}"
        assert lab.addresses["kuka-kvp"] == f"socket://127.0.0.1:{ports['kuka-kvp']}"
        with open_driver("geocom", lab.addresses["geocom"]) as tracker:
            assert np.all(np.isfinite(tracker.measure_point().value))
    assert not any(_listening(p) for p in ports.values())
