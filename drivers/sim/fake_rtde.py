"""Fake UR controller, RTDE receive side only, run as its own process.

``ur-rtde`` blocks in C++ while holding the GIL, so this server must not share
a process with a client. It listens on ``<host>:30004`` (the port ur-rtde always
uses) for a free loopback address 127.0.0.x, and takes joint angles and TCP
pose from the lab's control channel. It implements version negotiation,
controller version (reported 5.11.0, e-Series), output setup, start, pause
and data packages. It does not implement the URScript control program that
``RTDEControlInterface`` uploads, so motions cannot be commanded through it.

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


class RTDEServer:
    """One client at a time; streams the requested outputs at up to 125 Hz."""

    def __init__(self, host: str, control: str) -> None:
        self.client = LabClient(control)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.sock.bind((host, 30004))
        self.sock.listen(4)
        self.host = host
        self.state = self.client.call("state")
        self.frozen = False
        self.stop = threading.Event()
        self.t0 = time.monotonic()

    def poll_world(self) -> None:
        while not self.stop.is_set():
            try:
                if self.client.call("take_fault", device="ur", fault="disconnect")["armed"]:
                    self.stop.set()
                    self.sock.close()
                    return
                self.frozen = self.client.call("take_fault", device="ur",
                                               fault="frozen")["armed"] or self.frozen
                if not self.frozen:
                    self.state = self.client.call("state")
            except DriverError:
                self.stop.set()
                return
            time.sleep(0.005)

    def values(self, names: list[str], types: list[str]) -> list:
        out = []
        for n, t in zip(names, types, strict=True):
            if n == "timestamp":
                out.append(self.stamp)
            elif n in ("actual_q", "target_q"):
                out.append(self.state["q"])
            elif n in ("actual_TCP_pose", "target_TCP_pose"):
                out.append(self.state["tcp_pose"])
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

    @property
    def stamp(self) -> float:
        return self._stamp

    def serve(self, conn: socket.socket) -> None:
        conn.settimeout(0.5)
        names: list[str] = []
        types: list[str] = []
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
                    period = 1 / min(max(freq, 1.0), 125.0)
                    rid = 0 if "NOT_FOUND" in types else 1
                    conn.sendall(rtde.encode(ptype, bytes([rid]) + ",".join(types).encode()))
                elif ptype == rtde.SETUP_INPUTS:
                    n_in = len([n for n in payload.decode("ascii", "replace").split(",") if n])
                    conn.sendall(rtde.encode(ptype, b"\x00" + ",".join(["NOT_FOUND"] * n_in)
                                             .encode()))
                elif ptype == rtde.START:
                    streaming = bool(names) and "NOT_FOUND" not in types
                    conn.sendall(rtde.encode(ptype, bytes([1 if streaming else 0])))
                    next_t = time.monotonic()
                elif ptype == rtde.PAUSE:
                    streaming = False
                    conn.sendall(rtde.encode(ptype, b"\x01"))
            if streaming and time.monotonic() >= next_t:
                next_t += period
                if not self.frozen:
                    self._stamp = time.monotonic() - self.t0
                data = bytes([1]) + rtde.pack_values(types, self.values(names, types))
                conn.sendall(rtde.encode(rtde.DATA_PACKAGE, data))

    def run(self) -> None:
        threading.Thread(target=self.poll_world, daemon=True).start()
        self.sock.settimeout(0.2)
        while not self.stop.is_set():
            try:
                conn, _ = self.sock.accept()
            except (TimeoutError, OSError):
                continue
            threading.Thread(target=self._serve_closing, args=(conn,), daemon=True).start()

    def _serve_closing(self, conn: socket.socket) -> None:
        try:
            self.serve(conn)
        except (OSError, ProtocolError):
            pass
        finally:
            conn.close()


def free_loopback_host(port: int = 30004) -> str:
    """First 127.0.0.x (x >= 2) whose ``port`` is free."""
    for x in range(2, 255):
        host = f"127.0.0.{x}"
        with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
            try:
                s.bind((host, port))
            except OSError:
                continue
        return host
    raise OSError(f"no free loopback address for port {port}")


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
