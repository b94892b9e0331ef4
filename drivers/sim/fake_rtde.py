"""Fake UR controller (e-Series, PolyScope 5.11), run as its own process.

``ur-rtde`` blocks in C++ while holding the GIL, so this server must not share
a process with a client. ur-rtde hard-codes the ports, so the fake binds a free
loopback address 127.0.0.x (x >= 2) and serves there:

- RTDE, TCP 30004 (this module): protocol version 2, controller version
  (reported 5.11.0), output setup, input setup, start, pause, data packages in
  both directions (outputs streamed at the requested rate, up to 500 Hz;
  incoming input packages write the input registers);
- the dashboard server, TCP 29999, and the script interfaces, TCP 30002 and
  30003, with the emulation of ur-rtde's control program
  (:mod:`drivers.sim.fake_ur_control`), so ``rtde_control.RTDEControlInterface``
  connects with its default flags and ``moveJ`` / ``stopJ`` move the simulated
  robot.

Joint angles and TCP pose come from the lab's control channel (polled every
5 ms), joint targets go to it; faults ``disconnect`` (every socket closes and
the process ends) and ``frozen`` (the RTDE timestamp and state stop changing)
are taken from it.

Run: ``python -m drivers.sim.fake_rtde --control tcp://127.0.0.1:PORT``; it
prints ``ur=ur://127.0.0.x`` when ready.
"""

from __future__ import annotations

import argparse
import socket
import struct
import sys
import threading
import time

from drivers import rtde
from drivers.errors import DriverError, ProtocolError
from drivers.sim.control import LabClient
from drivers.sim.fake_ur_control import DashboardServer, ScriptServer, URController

#: every TCP port of a UR controller that ur-rtde uses (all hard-coded in the library)
UR_PORTS = (30004, 30003, 30002, 29999)
MAX_FREQUENCY = 500.0  # e-Series RTDE rate


class RTDEServer:
    """RTDE server on ``host:30004`` plus the dashboard and script servers of the same host."""

    def __init__(self, host: str, control: str) -> None:
        self.client = LabClient(control)
        self.host = host
        self.stop = threading.Event()
        self.ctrl = URController(self.client.call)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, 30004))
        self.sock.listen(4)
        self.servers = [DashboardServer(host, self.ctrl, self.stop),
                        ScriptServer(host, 30003, self.ctrl, self.stop),
                        ScriptServer(host, 30002, self.ctrl, self.stop)]
        self.conns: list[socket.socket] = []
        self.frozen = False
        self.t0 = time.monotonic()

    @property
    def state(self) -> dict:
        return self.ctrl.world_state

    def shutdown(self) -> None:
        """Close every socket (the ``disconnect`` fault, or the end of the process)."""
        self.stop.set()
        # The sockets close before the control program stops: a client whose link drops sees the
        # connection go, never a last state in which the program stopped (on a real controller
        # that happens behind the broken link, out of the client's sight).
        for s in (self.sock, *self.conns):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()
        for server in self.servers:
            server.close()
        self.ctrl.shutdown()

    def poll_world(self) -> None:
        while not self.stop.is_set():
            try:
                if self.client.call("take_fault", device="ur", fault="disconnect")["armed"]:
                    self.shutdown()
                    return
                self.frozen = self.client.call("take_fault", device="ur",
                                               fault="frozen")["armed"] or self.frozen
                if not self.frozen:
                    self.ctrl.world_state = self.client.call("state")
            except DriverError:
                self.shutdown()
                return
            time.sleep(0.005)

    def values(self, names: list[str], types: list[str]) -> list:
        q, qd = self.ctrl.joints() if not self.frozen else (self.state["q"], [0.0] * 6)
        out = []
        for n, t in zip(names, types, strict=True):
            if n == "timestamp":
                out.append(self._stamp)
            elif n in ("actual_q", "target_q"):
                out.append(q)
            elif n in ("actual_qd", "target_qd"):
                out.append(qd)
            elif n in ("actual_TCP_pose", "target_TCP_pose"):
                out.append(self.state["tcp_pose"])
            elif n in self.ctrl.outputs:
                out.append(self.ctrl.outputs[n])
            elif n == "runtime_state":
                out.append(self.ctrl.runtime_state)
            elif n == "robot_status_bits":
                out.append(self.ctrl.robot_status_bits)
            elif n == "safety_status_bits":
                out.append(1)  # normal mode, no protective or emergency stop
            elif t in ("VECTOR6D",):
                out.append([0.0] * 6)
            elif t == "VECTOR3D":
                out.append([0.0] * 3)
            elif t in ("VECTOR6INT32", "VECTOR6UINT32"):
                out.append([0] * 6)
            elif n == "robot_mode":
                out.append(7)  # ROBOT_MODE_RUNNING
            elif n == "safety_mode":
                out.append(1)  # NORMAL
            elif t == "DOUBLE":
                out.append(1.0 if n == "speed_scaling" else 0.0)
            elif t == "BOOL":
                out.append(False)
            else:
                out.append(0)
        return out

    def serve(self, conn: socket.socket) -> None:
        names: list[str] = []
        types: list[str] = []
        inputs: dict[int, tuple[list[str], list[str]]] = {}
        period = 1 / 125
        streaming = False
        buf = b""
        next_t = time.monotonic()
        self._stamp = 0.0
        while not self.stop.is_set():
            try:
                conn.settimeout(max(1e-3, next_t - time.monotonic()) if streaming else 0.2)
                chunk = conn.recv(4096)
                if not chunk:
                    return
                buf += chunk
            except TimeoutError:
                pass
            while len(buf) >= 3:
                size, ptype = rtde.decode_header(buf[:3])
                if len(buf) < 3 + size:
                    break
                payload, buf = buf[3:3 + size], buf[3 + size:]
                if ptype == rtde.REQUEST_PROTOCOL_VERSION:
                    ok = len(payload) == 2 and struct.unpack(">H", payload)[0] == 2
                    conn.sendall(rtde.encode(ptype, bytes([1 if ok else 0])))
                elif ptype == rtde.GET_URCONTROL_VERSION:
                    conn.sendall(rtde.encode(ptype, struct.pack(">4I", 5, 11, 0, 0)))
                elif ptype == rtde.SETUP_OUTPUTS:
                    freq, names = rtde.decode_setup_outputs(payload)
                    types = [rtde.output_type(n) for n in names]
                    period = 1 / min(max(freq, 1.0), MAX_FREQUENCY)
                    rid = 0 if "NOT_FOUND" in types else 1
                    conn.sendall(rtde.encode(ptype, bytes([rid]) + ",".join(types).encode()))
                elif ptype == rtde.SETUP_INPUTS:
                    in_names = rtde.decode_names(payload)
                    in_types = [rtde.input_type(n) for n in in_names]
                    rid = 0
                    if in_names and "NOT_FOUND" not in in_types and len(inputs) < 255:
                        rid = len(inputs) + 1
                        inputs[rid] = (in_names, in_types)
                    conn.sendall(rtde.encode(ptype, bytes([rid]) + ",".join(in_types).encode()))
                elif ptype == rtde.DATA_PACKAGE:
                    if payload and payload[0] in inputs:
                        in_names, in_types = inputs[payload[0]]
                        self.ctrl.set_inputs(in_names, rtde.unpack_values(in_types, payload[1:]))
                elif ptype == rtde.START:
                    streaming = bool(names) and "NOT_FOUND" not in types
                    conn.sendall(rtde.encode(ptype, bytes([1 if streaming else 0])))
                    next_t = time.monotonic()
                elif ptype == rtde.PAUSE:
                    streaming = False
                    conn.sendall(rtde.encode(ptype, b"\x01"))
            now = time.monotonic()
            if streaming and now >= next_t:
                next_t = max(next_t + period, now - period)
                if not self.frozen:
                    self._stamp = now - self.t0
                data = bytes([1]) + rtde.pack_values(types, self.values(names, types))
                conn.sendall(rtde.encode(rtde.DATA_PACKAGE, data))

    def run(self) -> None:
        threading.Thread(target=self.poll_world, daemon=True).start()
        for server in self.servers:
            server.start()
        self.sock.settimeout(0.2)
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except (TimeoutError, OSError):
                continue
            conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self.conns.append(conn)
            threading.Thread(target=self._serve_closing, args=(conn,), daemon=True).start()

    def _serve_closing(self, conn: socket.socket) -> None:
        try:
            self.serve(conn)
        except (OSError, ProtocolError):
            pass
        finally:
            conn.close()


def _free(host: str, port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((host, port))
        except OSError:
            return False
    return True


def free_loopback_host(ports: tuple[int, ...] = UR_PORTS) -> str:
    """First 127.0.0.x (x >= 2) on which every port of ``ports`` is free."""
    for x in range(2, 255):
        host = f"127.0.0.{x}"
        if all(_free(host, p) for p in ports):
            return host
    raise OSError(f"no free loopback address for ports {ports}")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--control", required=True, help="lab control address")
    parser.add_argument("--host", default=None, help="loopback address to bind (default: free)")
    args = parser.parse_args(argv)
    host = args.host or free_loopback_host()
    server = RTDEServer(host, args.control)
    print(f"ur=ur://{host}", flush=True)
    server.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
