"""Control channel of the simulated lab: JSON lines over loopback TCP.

Each request is one JSON object on one line; each reply is one JSON object
``{"ok": true, ...}`` or ``{"ok": false, "error": "..."}``. Commands (``cmd``):

- ``ping``
- ``addresses`` -> ``addresses`` (driver name -> address)
- ``state`` -> ``q`` (rad, controller convention), ``tcp_pose`` [x y z (m), rotation
  vector (rad)] from the encoders, ``load`` [6], ``load_name``, ``moving``, ``aimed``
- ``move`` with ``q`` (rad, controller) and ``speed`` (rad/s) -> ``duration`` (s)
- ``apply_load`` with ``wrench`` [f (N), m (N m)] in the base frame at the tool
  point, and ``name``; ``remove_load``
- ``aim`` with ``target`` (reflector name): where the tracker beam points
- ``fault`` with ``device`` (driver name), ``fault`` (see :mod:`drivers.sim.faults`)
  and ``count`` (-1: until cleared); ``clear_faults`` with optional ``device``;
  ``take_fault`` with ``device`` and ``fault`` -> ``armed`` (used by the UR fake)
- ``mark`` with ``context`` (a list of non-negative integers and names, e.g.
  ``[test, repeat, attempt, "phase"]``): the readings that follow draw their noise
  from (seed, instrument, context, sample) (:mod:`drivers.sim.noise`)
- ``truth`` -> ``stiffness``, ``tool_pose``, ``nominal_tool_pose``, ``deflection``,
  ``base_in_tracker``, ``sensor_mount`` (what the simulation knows; for tests)
- ``shutdown``: stop the lab
"""

from __future__ import annotations

import json
import socket
import socketserver
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from drivers.address import parse_address
from drivers.errors import ConnectionFailed, DeviceFault, DeviceTimeout, ProtocolError
from drivers.sim.world import World


def handle_command(world: World, req: dict[str, Any], addresses: dict[str, str],
                   on_shutdown: Callable[[], None] | None = None) -> dict[str, Any]:
    """Execute one control request against ``world``; never raises."""
    try:
        cmd = req.get("cmd")
        if cmd == "ping":
            return {"ok": True}
        if cmd == "addresses":
            return {"ok": True, "addresses": addresses}
        if cmd == "state":
            return {"ok": True, **world.state()}
        if cmd == "move":
            return {"ok": True, "duration": world.move(req["q"], float(req.get("speed", 1.0)))}
        if cmd == "apply_load":
            world.apply_load(np.asarray(req["wrench"], float), str(req.get("name", "")))
            return {"ok": True}
        if cmd == "remove_load":
            world.remove_load()
            return {"ok": True}
        if cmd == "aim":
            world.aim(str(req["target"]))
            return {"ok": True}
        if cmd == "fault":
            world.faults.inject(str(req["device"]), str(req["fault"]), int(req.get("count", 1)))
            return {"ok": True}
        if cmd == "take_fault":
            return {"ok": True, "armed": world.faults.take(str(req["device"]), str(req["fault"]))}
        if cmd == "clear_faults":
            world.faults.clear(req.get("device"))
            return {"ok": True}
        if cmd == "mark":
            context = req.get("context", [])
            if not isinstance(context, list) or not all(
                    isinstance(c, str) or (isinstance(c, int) and not isinstance(c, bool)
                                           and c >= 0) for c in context):
                raise ValueError("mark: context must be a list of names and integers >= 0")
            world.noise_streams.mark(*context)
            return {"ok": True}
        if cmd == "truth":
            return {"ok": True, "stiffness": world.k.tolist(),
                    "tool_pose": world.true_tool_pose().tolist(),
                    "nominal_tool_pose": world.nominal_tool_pose().tolist(),
                    "deflection": world.true_deflection().tolist(),
                    "base_in_tracker": world.base_in_tracker.tolist(),
                    "sensor_mount": world.sensor_mount.tolist()}
        if cmd == "shutdown":
            if on_shutdown is not None:
                threading.Thread(target=on_shutdown, daemon=True).start()
            return {"ok": True}
        return {"ok": False, "error": f"unknown command {cmd!r}"}
    except (KeyError, TypeError, ValueError) as err:
        return {"ok": False, "error": f"{type(err).__name__}: {err}"}
    except Exception as err:  # the world must keep serving whatever one request does
        return {"ok": False, "error": f"{type(err).__name__}: {err}"}


class ControlServer:
    """Threaded TCP server answering control requests on 127.0.0.1."""

    def __init__(self, world: World, addresses: dict[str, str],
                 on_shutdown: Callable[[], None] | None = None, port: int = 0) -> None:
        outer = self

        class Handler(socketserver.StreamRequestHandler):
            def handle(self) -> None:
                try:
                    for line in self.rfile:
                        self.wfile.write((json.dumps(self._answer(line)) + "\n").encode())
                except (ConnectionResetError, BrokenPipeError):
                    # the client went away (e.g. closed right after "shutdown"): nothing
                    # left to answer, and not an error of the lab
                    return

            def _answer(self, line: bytes) -> dict:
                try:
                    req = json.loads(line)
                    if not isinstance(req, dict):
                        raise ValueError("request must be a JSON object")
                except ValueError as err:
                    return {"ok": False, "error": f"bad JSON: {err}"}
                return handle_command(world, req, outer.addresses, on_shutdown)

        self.addresses = addresses
        self.server = socketserver.ThreadingTCPServer(("127.0.0.1", port), Handler)
        self.server.daemon_threads = True
        self.url = f"tcp://127.0.0.1:{self.server.server_address[1]}"
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True,
                                        name="lab-control")

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self.server.shutdown()
        self.server.server_close()


class LabClient:
    """Client of the control channel (tests, the acquisition runner's fake mode).

    Parameters
    ----------
    address : str
        ``tcp://127.0.0.1:PORT`` or ``lab://127.0.0.1:PORT`` as printed by the lab.
    """

    def __init__(self, address: str, timeout: float = 10.0) -> None:
        addr = parse_address(address)
        if addr.port is None:
            raise ConnectionFailed(f"{address!r}: control address needs a port")
        try:
            self._sock = socket.create_connection((addr.host, addr.port), timeout=timeout)
        except OSError as err:
            raise ConnectionFailed(f"lab control {address}: {err}") from err
        self._file = self._sock.makefile("rwb")
        self._lock = threading.Lock()

    def call(self, cmd: str, **fields: Any) -> dict[str, Any]:
        """Send one command; return the reply, raising :class:`DeviceFault` on ``ok: false``."""
        with self._lock:
            try:
                self._file.write((json.dumps({"cmd": cmd, **fields}) + "\n").encode())
                self._file.flush()
                line = self._file.readline()
            except TimeoutError as err:
                raise DeviceTimeout(f"lab control: no reply to {cmd!r}") from err
            except OSError as err:
                raise ConnectionFailed(f"lab control: {err}") from err
        if not line:
            raise ConnectionFailed("lab control channel closed")
        try:
            reply = json.loads(line)
        except ValueError as err:
            raise ProtocolError(f"lab control: bad reply {line[:80]!r}") from err
        if not reply.get("ok"):
            raise DeviceFault(f"lab refused {cmd!r}: {reply.get('error')}")
        return reply

    def close(self) -> None:
        try:
            self._file.close()
        finally:
            self._sock.close()

    def __enter__(self) -> LabClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
