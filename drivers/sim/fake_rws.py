"""Fake ABB controller: Robot Web Services 1.0 (RobotWare 6) or 2.0 (RobotWare 7).

An HTTP server (RWS 1.0: plain HTTP, Digest authentication) or HTTPS server (RWS 2.0:
a self-signed certificate made at start, Basic authentication) on loopback, with the
session cookies, content types and resource layout of :mod:`drivers.rws`, over the
lab's world. It runs the behaviour of ``drivers/rapid/StiffLoop.mod``: writing
``stiff_go`` TRUE while RAPID runs moves the robot to ``stiff_target`` in
``stiff_time`` seconds (simulated; never faster than ``max_speed`` on the leading axis)
and clears ``stiff_go`` when the motion ends; a RAPID stop halts the robot on its path
and leaves ``stiff_go`` TRUE (the program pointer stays on the ``MoveAbsJ``).

Resources: ``jointtarget`` of ``ROB_1`` (the world's angles, FlexPendant convention,
``rax_*`` strings with 5 decimals), RAPID execution state and start/stop, panel
controller state and operating mode, RAPID symbol data of the loop module (read,
write; a value of the wrong type gets 400), mastership request/release, ``/logout``.
JSON with ``?json=1`` (RWS 1.0) or ``Accept: application/hal+json;v=2.0`` (RWS 2.0),
else XHTML; RWS 2.0 answers 406 to an ``Accept`` or POST ``Content-Type`` without
``;v=2.0``. Errors carry a controller return code and message (the fake's codes are
its own, listed in :data:`CODES`; a real controller's differ).

Tests set :attr:`FakeRWS.mastership_holder` to another client's name (writes and
mastership requests then get 403), :attr:`FakeRWS.exec_state`, :attr:`FakeRWS.opmode`;
the lab's faults ``disconnect`` (the connection closes unanswered and every session is
forgotten), ``drop`` (no answer for :attr:`late_delay` s, then the connection closes)
and ``late`` (the answer comes after :attr:`late_delay` s) act on the next request.
"""

from __future__ import annotations

import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, quote, unquote, urlsplit

import numpy as np

from drivers import rws
from drivers.errors import ProtocolError
from drivers.sim.base import FakeServer
from drivers.sim.rws_auth import RwsAuth
from drivers.sim.world import World

MODULE = "T_ROB1/StiffLoop"
#: the fake's controller return codes (illustrative values)
CODES = {
    "mastership": (-1073445865, "Mastership is held by another client ({holder})"),
    "not_found": (-1073442795, "Resource not found"),
    "value": (-1073442816, "Invalid value for symbol {name}"),
    "state": (-1073445871, "Operation not allowed in the current controller state"),
}


class _Server(ThreadingHTTPServer):
    daemon_threads = True

    def __init__(self, fake: FakeRWS, context) -> None:
        self.fake, self.context = fake, context
        super().__init__(("127.0.0.1", 0), _Handler)

    def finish_request(self, request, client_address) -> None:
        if self.context is not None:  # TLS handshake in the connection's own thread
            try:
                request = self.context.wrap_socket(request, server_side=True)
            except OSError:
                return
        super().finish_request(request, client_address)


class _Handler(BaseHTTPRequestHandler):
    protocol_version = "HTTP/1.1"
    server_version = "FakeRWS/1"

    def log_message(self, *args: Any) -> None:  # quiet
        pass

    def do_GET(self) -> None:  # noqa: N802 - http.server's naming
        self.server.fake.handle(self, "GET")

    def do_POST(self) -> None:  # noqa: N802
        self.server.fake.handle(self, "POST")


class FakeRWS(FakeServer):
    """RWS on loopback over the lab's world (see the module docstring)."""

    def __init__(self, world: World, version: int = 1, max_speed: float = 2.0,
                 users: dict[str, str] | None = None) -> None:
        super().__init__(world)
        self.dialect = rws.Dialect(version)
        self.driver = "abb-rws" if version == 1 else "abb-rws2"
        self.device = self.driver
        user, password = self.dialect.default_user
        self.auth = RwsAuth(users or {user: password}, digest=not self.dialect.secure)
        context, self.cert_pem = None, b""
        if self.dialect.secure:
            from drivers.sim.tls_cert import self_signed_context

            context, self.cert_pem = self_signed_context()
        self.server = _Server(self, context)
        self.host, self.port = self.server.server_address[:2]
        scheme = "rws2" if self.dialect.secure else "rws"
        self.url = (f"{scheme}://{quote(user)}:{quote(password)}@{self.host}:{self.port}"
                    + ("?insecure=1" if self.dialect.secure else ""))
        self.max_speed = max_speed
        self.exec_state, self.ctrlstate, self.opmode = "running", "motoron", "AUTO"
        self.mastership_holder: str | None = None
        self.late_delay = 1.0
        self.symbols = {"stiff_go": "FALSE", "stiff_time": "10",
                        "stiff_target": rws.format_jointtarget(
                            np.degrees(world.joint_angles()))}
        self.transcript: list[tuple[str, str, int]] = []
        self._lock = threading.RLock()
        self._timer: threading.Timer | None = None
        self._motion: tuple[np.ndarray, np.ndarray, float, float] | None = None

    def _run(self) -> None:
        self.server.serve_forever(poll_interval=0.1)

    def _close(self) -> None:
        if self._timer is not None:
            self._timer.cancel()
        self.server.shutdown()
        self.server.server_close()

    # --- HTTP -------------------------------------------------------------
    def handle(self, h: _Handler, method: str) -> None:
        length = int(h.headers.get("Content-Length") or 0)
        body = h.rfile.read(length).decode("utf-8", "replace") if length else ""
        if self.fault("disconnect"):
            self.auth.drop_sessions()
            h.close_connection = True
            return
        if self.fault("drop"):
            time.sleep(self.late_delay)
            h.close_connection = True
            return
        if self.fault("late"):
            time.sleep(self.late_delay)
        parts = urlsplit(h.path)
        path = unquote(parts.path)
        query = {k: v[-1] for k, v in parse_qs(parts.query).items()}
        user = self.auth.session_user(h.headers.get("Cookie"))
        cookies: list[str] = []
        if user is None:
            user = self.auth.check(h.headers.get("Authorization"), method, h.path)
            if user is None:
                self._send(h, method, 401, None, {"WWW-Authenticate": self.auth.challenge()})
                return
            cookies = self.auth.open_session(user)
        if self.dialect.secure:
            accept = h.headers.get("Accept", "")
            if ";v=2.0" not in accept.replace(" ", ""):
                self._send(h, method, 406, None, cookies=cookies)
                return
            if method == "POST" and (body or h.headers.get("Content-Type")) \
                    and h.headers.get("Content-Type", "").replace(" ", "") != rws.FORM_V2:
                self._send(h, method, 406, None, cookies=cookies)
                return
            as_json = "json" in accept
        else:
            as_json = query.get("json") == "1"
        form = {k: v[-1] for k, v in parse_qs(body, keep_blank_values=True).items()}
        status, payload = self._route(method, path, query, form, h.headers.get("Cookie"))
        self._send(h, method, status, payload, cookies=cookies, as_json=as_json)

    def _send(self, h: _Handler, method: str, status: int, payload: Any,
              headers: dict[str, str] | None = None, cookies: list[str] | None = None,
              as_json: bool = True) -> None:
        self.transcript.append((method, h.path, status))
        if payload is None:
            data, ctype = b"", None
        elif as_json:
            data = json.dumps(payload).encode("utf-8")
            ctype = rws.HAL_JSON if self.dialect.secure else "application/json"
        else:
            data = _xhtml(payload).encode("utf-8")
            ctype = "application/xhtml+xml;v=2.0" if self.dialect.secure \
                else "application/xhtml+xml"
        h.send_response(status)
        for key, value in (headers or {}).items():
            h.send_header(key, value)
        for c in cookies or []:
            h.send_header("Set-Cookie", c)
        if ctype:
            h.send_header("Content-Type", ctype)
        h.send_header("Content-Length", str(len(data)))
        h.end_headers()
        if data:
            h.wfile.write(data)

    def _error(self, status: int, key: str, **fmt: str) -> tuple[int, Any]:
        code, msg = CODES[key]
        return status, self.dialect.error(code, msg.format(**fmt))

    def _ok(self, *states: dict[str, Any]) -> tuple[int, Any]:
        return 200, self.dialect.wrap(list(states), base="/rw/")

    # --- resources --------------------------------------------------------
    def _route(self, method: str, path: str, query: dict[str, str], form: dict[str, str],
               cookie: str | None) -> tuple[int, Any]:
        d = self.dialect
        action = query.get("action", "")
        if path == "/logout" and method == "GET":
            self.auth.end_session(cookie)
            return 204, None
        if method == "GET":
            if path == d.jointtarget()[0]:
                q = np.degrees(self.world.joint_angles())
                state = {"_type": "ms-jointtarget", "_title": "ROB_1",
                         **{f"rax_{i + 1}": f"{v:.5f}" for i, v in enumerate(q)},
                         **{f"eax_{c}": rws.NO_AXIS for c in "abcdef"}}
                return self._ok(state)
            if path == d.execution()[0] and not action:
                return self._ok({"_type": "rap-execution", "_title": "execution",
                                 "ctrlexecstate": self.exec_state, "cycle": "forever"})
            if path == d.ctrlstate()[0]:
                return self._ok({"_type": "pnl-ctrlstate", "_title": "ctrlstate",
                                 "ctrlstate": self.ctrlstate})
            if path == d.opmode()[0]:
                return self._ok({"_type": "pnl-opmode", "_title": "opmode",
                                 "opmode": self.opmode})
            name = self._symbol_name(path)
            if name is not None:
                with self._lock:
                    value = self.symbols[name]
                return self._ok({"_type": "rap-data", "_title": f"RAPID/{MODULE}/{name}",
                                 "value": value})
            return self._error(404, "not_found")
        # POST
        who = cookie or "client"
        if self._is(path, action, d.mastership("request")) or \
                self._is(path, action, ("/rw/mastership", {"action": "request"})) or \
                self._is(path, action, ("/rw/mastership/request", {})):
            with self._lock:
                if self.mastership_holder not in (None, who):
                    return self._error(403, "mastership", holder=self.mastership_holder)
                self.mastership_holder = who
            return 204, None
        if self._is(path, action, d.mastership("release")) or \
                self._is(path, action, ("/rw/mastership", {"action": "release"})) or \
                self._is(path, action, ("/rw/mastership/release", {})):
            with self._lock:
                if self.mastership_holder not in (None, who):
                    return self._error(403, "mastership", holder=self.mastership_holder)
                self.mastership_holder = None
            return 204, None
        if self._is(path, action, d.rapid("stop")):
            self._rapid_stop()
            return 204, None
        if self._is(path, action, d.rapid("start")):
            if self.ctrlstate != "motoron" or self.opmode != "AUTO":
                return self._error(400, "state")
            self.exec_state = "running"
            return 204, None
        name = self._symbol_name(path, setting=True, action=action)
        if name is not None:
            with self._lock:
                if self.mastership_holder not in (None, who):
                    return self._error(403, "mastership", holder=self.mastership_holder)
            return self._write(name, form.get("value"))
        return self._error(404, "not_found")

    @staticmethod
    def _is(path: str, action: str, resource: tuple[str, dict[str, str]]) -> bool:
        want_path, want_query = resource
        return path == want_path and action == want_query.get("action", "")

    def _symbol_name(self, path: str, setting: bool = False, action: str = "") -> str | None:
        if self.dialect.secure:
            prefix, suffix = f"/rw/rapid/symbol/RAPID/{MODULE}/", "/data"
        else:
            prefix, suffix = f"/rw/rapid/symbol/data/RAPID/{MODULE}/", ""
            if setting != (action == "set"):
                return None
        if not (path.startswith(prefix) and path.endswith(suffix)):
            return None
        name = path[len(prefix):len(path) - len(suffix)]
        return name if name in self.symbols else None

    def _write(self, name: str, value: str | None) -> tuple[int, Any]:
        if value is None:
            return self._error(400, "value", name=name)
        try:
            if name == "stiff_go":
                go = rws.parse_bool(value)
                value = rws.format_bool(go)
            elif name == "stiff_target":
                rws.parse_jointtarget(value)
            else:
                float(value)
        except (ProtocolError, ValueError):
            return self._error(400, "value", name=name)
        with self._lock:
            self.symbols[name] = value
            if name == "stiff_go" and go and self.exec_state == "running" \
                    and self._timer is None:
                self._start_motion()
        return 204, None

    # --- the RAPID loop ----------------------------------------------------
    def _start_motion(self) -> None:
        target = np.radians(rws.parse_jointtarget(self.symbols["stiff_target"]))
        seconds = max(0.5, float(self.symbols["stiff_time"]))
        start = self.world.joint_angles()
        step = float(np.max(np.abs(target - start)))
        try:
            duration = self.world.move(target, min(self.max_speed, max(step / seconds, 1e-9)))
        except ValueError:  # RAPID stops with a motion error; the flag stays set
            self.exec_state = "stopped"
            return
        self._motion = (start, target, time.monotonic(), duration)
        self._timer = threading.Timer(duration, self._end_motion)
        self._timer.daemon = True
        self._timer.start()

    def _end_motion(self) -> None:
        with self._lock:
            self.symbols["stiff_go"] = "FALSE"
            self._timer, self._motion = None, None

    def _rapid_stop(self) -> None:
        with self._lock:
            self.exec_state = "stopped"
            if self._timer is not None:
                self._timer.cancel()
                self._timer = None
            if self._motion is not None:
                start, target, t0, duration = self._motion
                frac = min(1.0, (time.monotonic() - t0) / duration) if duration > 0 else 1.0
                self.world.move(start + frac * (target - start), 1e6)
                self._motion = None


def _xhtml(payload: Any) -> str:
    """A minimal XHTML rendering of a JSON answer (``li`` per state, ``span`` per field)."""
    states = payload.get("state") or payload.get("_embedded", {}).get("_state", [])
    items = []
    for s in states:
        spans = "".join(f'<span class="{k}">{v}</span>' for k, v in s.items()
                        if not k.startswith("_"))
        items.append(f'<li class="{s.get("_type", "")}" title="{s.get("_title", "")}">'
                     f"{spans}</li>")
    return ('<?xml version="1.0" encoding="utf-8"?><html xmlns="http://www.w3.org/1999/xhtml">'
            f'<body><div class="state"><ul>{"".join(items)}</ul></div></body></html>')
