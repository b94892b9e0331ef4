"""ABB robot (IRC5 / OmniCore) through Robot Web Services and the shipped RAPID module.

The controller runs ``drivers/rapid/StiffLoop.mod`` (see ``drivers/rapid/README.md``):
it waits for ``stiff_go``, moves ``MoveAbsJ`` to ``stiff_target`` in ``stiff_time``
seconds with a fine point, then clears ``stiff_go``. This driver reads the joints at
``/rw/motionsystem/mechunits/ROB_1/jointtarget``, checks the controller state (motors
on) and the RAPID execution state,
requests mastership, writes the three RAPID variables, releases mastership, polls
``stiff_go``, and stops RAPID on abort or timeout. Requests go through ``requests``
(Digest authentication for RWS 1.0, Basic for 2.0, one session keeping the
controller's ``-http-session-`` and ``ABBCX`` cookies); dialects in :mod:`drivers.rws`.

Addresses: ``rws://user:password@controller[:80]`` (RobotWare 6, RWS 1.0, HTTP) and
``rws2://user:password@controller[:443]`` (RobotWare 7, RWS 2.0, HTTPS; the
certificate is checked unless ``insecure=1``, or against ``ca=FILE``). Without user
and password each version's default user is used. Options: ``max_speed`` (rad/s,
default 1.0), ``motion_timeout`` (s, 120), ``poll`` (s, 0.05), ``task`` (T_ROB1),
``module`` (StiffLoop), ``mechunit`` (ROB_1).

Joint angles are in rad in the API and degrees on the wire, both in the controller's
convention (the FlexPendant's).
"""

from __future__ import annotations

import time
from typing import Any
from urllib.parse import quote

import numpy as np

from drivers import rws
from drivers.address import parse_address
from drivers.errors import (
    AddressError,
    ConnectionFailed,
    DeviceFault,
    DeviceTimeout,
    DriverError,
    ProtocolError,
)
from drivers.readings import Pose
from drivers.roles import RobotController
from drivers.safety import check_reached

MIN_TIME = 0.5  # s, the RAPID module's own floor for stiff_time


class ABBRWSRobot(RobotController):
    """ABB robot via RWS 1.0 or 2.0 (see the module docstring)."""

    def __init__(self, address: str, *, timeout: float = 2.0, **_: Any) -> None:
        super().__init__(address, timeout=timeout)
        addr = parse_address(address)
        if addr.scheme not in ("rws", "rws2"):
            raise AddressError(f"{address!r}: expected rws://user:password@controller "
                               "(RobotWare 6) or rws2://... (RobotWare 7)")
        self.dialect = rws.Dialect(2 if addr.scheme == "rws2" else 1)
        addr = addr.with_default_port(self.dialect.default_port)
        self.host, self.port = addr.host, int(addr.port)
        user, password = self.dialect.default_user
        self.user = addr.user or user
        self._password = addr.password if addr.user else password
        self.max_speed = addr.float_option("max_speed", 1.0)
        self.motion_timeout = addr.float_option("motion_timeout", 120.0)
        self.poll = addr.float_option("poll", 0.05)
        task = addr.option("task", "T_ROB1")
        module = addr.option("module", "StiffLoop")
        self.mechunit = addr.option("mechunit", "ROB_1")
        self.symbols = f"{task}/{module}"
        self.insecure = addr.option("insecure", "0") in ("1", "true", "yes")
        self.ca = addr.option("ca")
        scheme = "https" if self.dialect.secure else "http"
        self.base = f"{scheme}://{self.host}:{self.port}"
        self._session = None

    # --- HTTP -------------------------------------------------------------
    def _connect(self) -> None:
        import requests

        session = requests.Session()
        # no proxy, netrc or CA bundle from the environment: the controller is on the
        # cell's network, and only the address decides how its certificate is checked
        session.trust_env = False
        if self.dialect.secure:
            session.auth = requests.auth.HTTPBasicAuth(self.user, self._password)
            session.headers["Accept"] = rws.HAL_JSON
            session.verify = False if self.insecure else (self.ca or True)
        else:
            session.auth = requests.auth.HTTPDigestAuth(self.user, self._password)
        self._session = session
        try:
            self._state(self.dialect.execution(), "rap-execution")
        except BaseException:
            self._close()
            raise

    def _close(self) -> None:
        if self._session is not None:
            try:
                self._request("GET", ("/logout", {}), expect=(200, 204))
            except DriverError:
                pass
            self._session.close()
            self._session = None

    def _request(self, method: str, resource: tuple[str, dict[str, str]],
                 data: dict[str, str] | None = None, expect=(200, 201, 204)) -> Any:
        import warnings

        import requests
        import urllib3

        if self._session is None:
            raise ConnectionFailed(f"{self.base}: not connected")
        path, query = resource
        params = dict(query)
        headers = {}
        if not self.dialect.secure:
            params["json"] = "1"
        elif data is not None or method == "POST":
            headers["Content-Type"] = rws.FORM_V2
        url = self.base + quote(path, safe="/")
        try:
            with warnings.catch_warnings():  # insecure=1 was asked for: no warning per call
                warnings.simplefilter("ignore", urllib3.exceptions.InsecureRequestWarning)
                reply = self._session.request(method, url, params=params, data=data or {},
                                              headers=headers, timeout=self.timeout,
                                              verify=self._session.verify)
        except requests.exceptions.SSLError as err:
            raise ConnectionFailed(f"{self.base}: TLS certificate refused ({err}); add "
                                   "insecure=1 for a self-signed one, or ca=FILE") from err
        except requests.exceptions.Timeout as err:
            raise DeviceTimeout(f"{self.base}: {method} {path}: no answer within "
                                f"{self.timeout:g} s") from err
        except requests.exceptions.RequestException as err:
            raise ConnectionFailed(f"{self.base}: {method} {path}: {err}") from err
        if reply.status_code == 401:
            raise ConnectionFailed(f"{self.base}: authentication refused for user "
                                   f"{self.user!r} (HTTP 401)")
        body = None
        if reply.content:
            try:
                body = reply.json()
            except ValueError:
                body = None
        if reply.status_code not in expect:
            code, msg = self.dialect.status(body)
            detail = f": {msg} (controller code {code})" if code is not None else ""
            raise DeviceFault(f"{self.base}: {method} {path} refused: HTTP "
                              f"{reply.status_code} {reply.reason}{detail}")
        return body

    def _state(self, resource, kind: str) -> dict[str, Any]:
        states = self.dialect.states(self._request("GET", resource))
        if not states:
            raise ProtocolError(f"{self.base}: {resource[0]}: empty state")
        if states[0].get("_type") != kind:
            raise ProtocolError(f"{self.base}: {resource[0]}: answer of type "
                                f"{states[0].get('_type')!r}, expected {kind!r}")
        return states[0]

    # --- RAPID ------------------------------------------------------------
    def read_symbol(self, name: str) -> str:
        """Current value (RAPID text) of ``name`` in the loop module."""
        state = self._state(self.dialect.symbol(f"{self.symbols}/{name}"), "rap-data")
        return rws.state_value(state, "value", "rap-data")

    def write_symbol(self, name: str, value: str) -> None:
        """Write RAPID text ``value`` to ``name`` of the loop module (needs mastership)."""
        self._request("POST", self.dialect.symbol_set(f"{self.symbols}/{name}"),
                      {"value": value})

    def execution_state(self) -> str:
        """``running`` or ``stopped``."""
        state = self._state(self.dialect.execution(), "rap-execution")
        return rws.state_value(state, "ctrlexecstate", "rap-execution")

    def controller_state(self) -> str:
        """``motoron``, ``motoroff``, ``guardstop``, ``emergencystop``, ..."""
        state = self._state(self.dialect.ctrlstate(), "pnl-ctrlstate")
        return rws.state_value(state, "ctrlstate", "pnl-ctrlstate")

    def _write_motion(self, q_deg: np.ndarray, seconds: float) -> None:
        self._request("POST", self.dialect.mastership("request"))
        try:
            self.write_symbol("stiff_target", rws.format_jointtarget(q_deg))
            self.write_symbol("stiff_time", f"{seconds:.3f}")
            self.write_symbol("stiff_go", rws.format_bool(True))
        finally:
            try:
                self._request("POST", self.dialect.mastership("release"))
            except DriverError:
                pass

    # --- role -------------------------------------------------------------
    def _read_joints(self) -> np.ndarray:
        state = self._state(self.dialect.jointtarget(self.mechunit), "ms-jointtarget")
        return np.deg2rad(rws.joint_degrees(state))

    def _read_tool_pose(self) -> Pose | None:
        return None  # depends on the active tool and work object; the analysis uses joints

    def _move_joints(self, q: np.ndarray, speed: float, acceleration: float) -> None:
        ctrl = self.controller_state()
        if ctrl != "motoron":
            raise DeviceFault(f"{self.base}: controller state {ctrl!r}: the motors must be "
                              "on (motoron) before moving")
        if self.execution_state() != "running":
            raise DeviceFault(f"{self.base}: RAPID is stopped: start StiffLoop's main "
                              "(drivers/rapid/README.md) before moving")
        start = self._read_joints()
        step = float(np.max(np.abs(q - start)))
        # \T sets the motion's duration: the leading axis moves at most `speed`
        seconds = max(MIN_TIME, step / min(speed, self.max_speed))
        self._write_motion(np.rad2deg(q), seconds)
        deadline = time.monotonic() + self.motion_timeout
        polls = 0
        while rws.parse_bool(self.read_symbol("stiff_go")):
            polls += 1
            if time.monotonic() > deadline:
                self.stop_quietly()
                raise DeviceTimeout(f"motion not finished after {self.motion_timeout} s; "
                                    "RAPID stopped")
            if polls % 20 == 0 and self.execution_state() != "running":
                raise DeviceFault(f"{self.base}: RAPID stopped during the motion")
            time.sleep(self.poll)
        check_reached(self._read_joints(), q)

    def _stop(self) -> None:
        self._request("POST", self.dialect.rapid("stop"),
                      {"stopmode": "stop", "usetsp": "normal"})

    def describe(self) -> dict[str, Any]:
        d = super().describe()
        if self._password:  # never write the password into a run's metadata
            d["address"] = self.address.replace(f":{quote(self._password)}@", ":***@") \
                .replace(f":{self._password}@", ":***@")
        d.update(protocol=f"ABB RWS {self.dialect.version}.0", user=self.user,
                 program="drivers/rapid/StiffLoop.mod", max_speed=self.max_speed)
        return d
