"""Nothing of the simulated lab leaves loopback; the Net CAN fake is reached across processes.

* The ATI Net CAN fake of ``campaign lab --fake`` sits on a socketcand server on
  127.0.0.1: the real driver (python-can's ``socketcand`` client) reads the
  world's wrench through it from another process, a raw TCP client speaking
  the socketcand ASCII protocol gets the documented frames, and one request
  gets exactly its answers (the fake does not answer answers).
* Every socket of the lab's process tree, for the default lab and the lab of
  every protocol in protocols/, is bound to a loopback address (read from
  /proc/net/{tcp,tcp6,udp,udp6} by the inodes of the processes' descriptors).
* In a network namespace whose only other interface is a veth pair carrying the
  default and the multicast routes, a default lab serving the Net CAN and Net
  F/T drivers sends zero packets through the veth pair.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from drivers.registry import open_driver
from drivers.sim.control import LabClient
from tests.drivers.test_lab_protocols import PROTOCOLS, ROOT, _start

pytestmark = pytest.mark.timeout(180)


def _stop(proc: subprocess.Popen, control: str) -> None:
    try:
        with LabClient(control) as client:
            client.call("shutdown")
        proc.wait(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _lines(sock: socket.socket, want: int, timeout: float) -> list[str]:
    """Read ``< ... >`` messages from a socketcand connection (at most ``want``)."""
    sock.settimeout(0.05)
    buf, out = "", []
    end = time.monotonic() + timeout
    while time.monotonic() < end and len(out) < want:
        try:
            chunk = sock.recv(4096).decode("ascii")
        except TimeoutError:
            continue
        if not chunk:
            break
        buf += chunk
        while ">" in buf:
            msg, buf = buf.split(">", 1)
            out.append(msg[msg.index("<"):] + ">")
    return out


def _open_raw(url: str) -> socket.socket:
    """A socketcand raw-mode connection to the bus of a ``can://`` address."""
    from drivers.address import parse_address

    addr = parse_address(url)
    sock = socket.create_connection((addr.option("host"), int(addr.option("port"))), 5)
    assert _lines(sock, 1, 5) == ["< hi >"]
    sock.sendall(f"< open {addr.path} >".encode())
    assert _lines(sock, 1, 5) == ["< ok >"]
    sock.sendall(b"< rawmode >")
    assert _lines(sock, 1, 5) == ["< ok >"]
    return sock


def test_netcan_fake_of_the_default_lab_answers_the_real_driver_across_processes():
    proc, addresses = _start(["--fake", "--time-scale", "200", "--seed", "3"])
    try:
        url = addresses["ati-netcan"]
        assert "interface=socketcand" in url and "host=127.0.0.1" in url
        wrench = np.array([40.0, -120.0, -500.0, 8.0, -3.0, 2.0])
        with LabClient(addresses["control"]) as client:
            client.call("apply_load", wrench=wrench.tolist())
            time.sleep(0.2)  # 80 settling time constants at time scale 200
            truth = client.call("truth")
        T = np.asarray(truth["tool_pose"]) @ np.asarray(truth["sensor_mount"])
        R, o, p = T[:3, :3], T[:3, 3], np.asarray(truth["tool_pose"])[:3, 3]
        expected = np.concatenate([R.T @ wrench[:3], R.T @ (wrench[3:] + np.cross(p - o,
                                                                                 wrench[:3]))])
        with open_driver("ati-netcan", url) as sensor:
            assert sensor.units == ("N", "N-m")
            w = sensor.read_wrench(200)
        # default lab noise: 0.5 N and 0.05 N m per sample; 200 samples
        np.testing.assert_allclose(w.spread, [0.5] * 3 + [0.05] * 3, rtol=0.25)
        tol = 5 * np.array([0.5] * 3 + [0.05] * 3) / np.sqrt(200) + 2e-3
        assert np.all(np.abs(w.value - expected) < tol), (w.value, expected)
    finally:
        _stop(proc, addresses["control"])


def test_netcan_bus_speaks_socketcand_and_answers_requests_only():
    proc, addresses = _start(["--fake", "--instruments", "ati-netcan", "--seed", "3"])
    try:
        url = addresses["ati-netcan"]
        requester, listener = _open_raw(url), _open_raw(url)
        try:
            # counts per unit (opcode 0x7): 1000 counts/N, 10000 counts/(N m), big-endian int32
            requester.sendall(b"< send 7F7 0 >")
            got = _lines(requester, 5, 1.0)
            assert len(got) == 1 and got[0].startswith("< frame 7F7 "), got
            assert got[0].split()[-2] == "000003E800002710"
            # unit codes (0x8): N, N-m
            requester.sendall(b"< send 7F8 0 >")
            assert _lines(requester, 5, 1.0)[0].split()[-2] == "0203"
            # another node on the bus hears the requests and the answers, each once; a
            # strain-gauge request (0x0) is answered by exactly two frames (0x0 and 0x1)
            requester.sendall(b"< send 7F0 0 >")
            answers = _lines(requester, 10, 1.0)
            assert [a.split()[2] for a in answers] == ["7F0", "7F1"], answers
            heard = _lines(listener, 50, 1.0)
            ids = [h.split()[2] for h in heard]
            assert ids == ["7F7", "7F7", "7F8", "7F8", "7F0", "7F0", "7F1"], heard
            # an answer-shaped frame (8 data bytes on 0x7F0) is not a request
            requester.sendall(b"< send 7F0 8 0 0 0 1 0 2 0 3 >")
            assert _lines(requester, 5, 0.5) == []
            requester.sendall(b"< send 7F0 2 1 >")  # DLC 2 with one byte: refused
            assert _lines(requester, 5, 1.0)[0].startswith("< error")
        finally:
            requester.close()
            listener.close()
    finally:
        _stop(proc, addresses["control"])


def _socket_inodes(pid: int) -> set[int]:
    """Inodes of the sockets held by ``pid`` and its descendants."""
    found: set[int] = set()
    todo = [pid]
    while todo:
        p = todo.pop()
        try:
            for fd in os.listdir(f"/proc/{p}/fd"):
                try:
                    target = os.readlink(f"/proc/{p}/fd/{fd}")
                except OSError:
                    continue
                if target.startswith("socket:["):
                    found.add(int(target[8:-1]))
            for task in os.listdir(f"/proc/{p}/task"):
                with open(f"/proc/{p}/task/{task}/children") as f:
                    todo.extend(int(c) for c in f.read().split())
        except (FileNotFoundError, ProcessLookupError):
            continue
    return found


def _inet_table() -> dict[int, tuple[str, str, str]]:
    """inode -> (table, local address as text, state) from /proc/net/{tcp,udp}{,6}."""
    table: dict[int, tuple[str, str, str]] = {}
    for name in ("tcp", "tcp6", "udp", "udp6"):
        with open(f"/proc/net/{name}") as f:
            next(f)
            for line in f:
                cols = line.split()
                hexaddr = cols[1].split(":")[0]
                raw = bytes.fromhex(hexaddr)
                if len(raw) == 4:
                    text = socket.inet_ntop(socket.AF_INET, raw[::-1])
                else:  # four little-endian 32-bit words
                    words = b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4))
                    text = socket.inet_ntop(socket.AF_INET6, words)
                table[int(cols[9])] = (name, text, cols[3])
    return table


def _is_loopback(text: str) -> bool:
    return text.startswith("127.") or text == "::1" or text.startswith("::ffff:127.")


def _unix_inodes() -> set[int]:
    with open("/proc/net/unix") as f:
        next(f)
        return {int(line.split()[6]) for line in f if len(line.split()) > 6}


@pytest.mark.parametrize("args", [[], *[["--protocol", str(p)] for p in PROTOCOLS]],
                         ids=["default", *[p.name for p in PROTOCOLS]])
def test_every_fake_listens_on_loopback_only(args):
    proc, addresses = _start(["--fake", "--time-scale", "200", *args])
    try:
        if any(name == "ur" for name in addresses):
            time.sleep(0.5)  # the UR child has bound its servers before printing its address
        inodes = _socket_inodes(proc.pid)
        inet = _inet_table()
        unix = _unix_inodes()
        mine = {i: inet[i] for i in inodes if i in inet}
        assert mine, "the lab holds no inet socket: the check would prove nothing"
        listening = [v for v in mine.values() if v[0].startswith("udp") or v[2] == "0A"]
        assert len(listening) >= len([u for u in addresses.values() if "127." in u]) - 2
        outside = {i: v for i, v in mine.items() if not _is_loopback(v[1])}
        assert not outside, f"sockets not on loopback: {outside} ({addresses})"
        # every other socket is a Unix socket (no raw, packet or netlink sockets)
        assert inodes <= set(mine) | unix, inodes - set(mine) - unix
    finally:
        _stop(proc, addresses["control"])


NAMESPACE_SCRIPT = r"""
set -e
echo 1 > /proc/sys/net/ipv6/conf/default/disable_ipv6
echo 1 > /proc/sys/net/ipv6/conf/all/disable_ipv6
ip link set lo up
ip link add vx0 type veth peer name vx1
ip link set vx0 up
ip link set vx1 up
ip addr add 10.203.0.1/24 dev vx0
ip route add default via 10.203.0.2 dev vx0
ip route add 224.0.0.0/4 dev vx0
exec "$PYTHON" "$HELPER"
"""

NAMESPACE_HELPER = r"""
import json, sys, time
def packets():
    out = {}
    for line in open('/proc/net/dev').read().splitlines()[2:]:
        name, _, rest = line.partition(':')
        cols = rest.split()
        out[name.strip()] = (int(cols[1]), int(cols[9]))  # rx, tx packets
    return out
before = packets()
from tests.drivers.test_lab_protocols import _start
from drivers.registry import open_driver
from drivers.sim.control import LabClient
proc, addresses = _start(['--fake', '--time-scale', '200'])
read = {}
with open_driver('ati-netcan', addresses['ati-netcan']) as can_sensor:
    read['netcan'] = can_sensor.read_wrench(100).value.tolist()
with open_driver('ati-netft', addresses['ati-netft']) as netft:
    read['netft'] = netft.read_wrench(100).value.tolist()
time.sleep(1.0)  # the old multicast fake sent about 3 frames/s at rest
with LabClient(addresses['control']) as client:
    client.call('shutdown')
proc.wait(20)
after = packets()
print(json.dumps({'before': before, 'after': after, 'read': read,
                  'netcan': addresses['ati-netcan']}))
"""


def test_default_lab_sends_nothing_out_of_a_namespace_with_a_veth_pair(tmp_path):
    missing = [tool for tool in ("unshare", "ip") if shutil.which(tool) is None]
    if missing:
        pytest.skip(f"network namespace test needs {' and '.join(missing)} "
                    "(util-linux, iproute2)")
    probe = subprocess.run(["unshare", "-n", "ip", "link", "add", "vp0", "type", "veth",
                            "peer", "name", "vp1"], capture_output=True, text=True)
    if probe.returncode != 0:
        pytest.skip("network namespaces with veth pairs are not allowed here "
                    f"(unshare -n ... ip link add type veth: {probe.stderr.strip()})")
    helper = tmp_path / "ns_helper.py"
    helper.write_text(NAMESPACE_HELPER)
    env = dict(os.environ, PYTHON=sys.executable, HELPER=str(helper),
               PYTHONPATH=os.pathsep.join([str(ROOT), *filter(None, [os.environ.get(
                   "PYTHONPATH")])]))
    done = subprocess.run(["unshare", "-n", "sh", "-c", NAMESPACE_SCRIPT], capture_output=True,
                          text=True, env=env, cwd=ROOT, timeout=150)
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert np.all(np.isfinite(report["read"]["netcan"])), report
    assert np.all(np.isfinite(report["read"]["netft"])), report
    for dev in ("vx0", "vx1"):
        rx0, tx0 = report["before"][dev]
        rx1, tx1 = report["after"][dev]
        assert (tx1 - tx0, rx1 - rx0) == (0, 0), (dev, report)
    # the loopback interface carried the traffic (the check counts real packets)
    assert report["after"]["lo"][1] - report["before"]["lo"][1] > 100, report


def test_lab_refuses_a_can_interface_that_could_leave_the_host(capsys):
    from campaign.cli import main

    assert main(["lab", "--fake", "--can-interface", "udp_multicast"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "udp_multicast" in err[0] and "socketcand" in err[0], err

