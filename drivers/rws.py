"""ABB Robot Web Services: the two dialects (RWS 1.0 on RobotWare 6, RWS 2.0 on 7).

Facts from ABB's *Robot Web Services* application manual (3HAC050973-001, RWS 1.0)
and its RobotWare 7 edition (RWS 2.0):

=====================  ====================================  ===============================
                       RWS 1.0 (IRC5, RobotWare 6)           RWS 2.0 (OmniCore, RobotWare 7)
=====================  ====================================  ===============================
transport              HTTP, port 80                         HTTPS, port 443 (self-signed)
authentication         Digest (realm validusers@robapi.abb)  Basic
default user           ``Default User`` / ``robotics``       ``Admin`` / ``robotics``
JSON                   query ``json=1``: application/json    ``Accept: application/hal+json;v=2.0``
POST body              form-encoded                          form-encoded, ``Content-Type:
                                                             application/x-www-form-urlencoded;v=2.0``
resource state         ``_embedded._state[0]``               top-level ``state[0]``
errors                 ``_embedded.status.code/msg``         ``status.code/msg``
actions                query ``action=set`` etc.             path style: ``.../data``, ``.../stop``
=====================  ====================================  ===============================

Both set the session cookies ``-http-session-`` and ``ABBCX`` on the first
authenticated answer; a client that sends them back is not asked to authenticate again.
Joint values are strings (``"rax_1": "12.5"``, degrees), a ``jointtarget`` as RAPID
text ``[[a1,..,a6],[e1,..,e6]]`` with 9E+09 for absent external axes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from drivers.errors import ProtocolError

REALM = "validusers@robapi.abb"
HAL_JSON = "application/hal+json;v=2.0"
FORM_V2 = "application/x-www-form-urlencoded;v=2.0"
NO_AXIS = "9E+09"
_JOINTTARGET = re.compile(r"^\s*\[\s*\[([^\[\]]*)\]\s*,\s*\[([^\[\]]*)\]\s*\]\s*$")


@dataclass(frozen=True)
class Dialect:
    """How one RWS version spells a request; ``version`` is 1 or 2."""

    version: int

    @property
    def secure(self) -> bool:
        return self.version == 2

    @property
    def default_port(self) -> int:
        return 443 if self.secure else 80

    @property
    def default_user(self) -> tuple[str, str]:
        return ("Admin", "robotics") if self.secure else ("Default User", "robotics")

    # --- resources: (path, query) ----------------------------------------
    def jointtarget(self, mechunit: str = "ROB_1") -> tuple[str, dict[str, str]]:
        return f"/rw/motionsystem/mechunits/{mechunit}/jointtarget", {}

    def execution(self) -> tuple[str, dict[str, str]]:
        return "/rw/rapid/execution", {}

    def ctrlstate(self) -> tuple[str, dict[str, str]]:
        return ("/rw/panel/ctrl-state" if self.secure else "/rw/panel/ctrlstate"), {}

    def opmode(self) -> tuple[str, dict[str, str]]:
        return "/rw/panel/opmode", {}

    def symbol(self, name: str) -> tuple[str, dict[str, str]]:
        """Read resource of RAPID symbol ``T_ROB1/Module/name``."""
        if self.secure:
            return f"/rw/rapid/symbol/RAPID/{name}/data", {}
        return f"/rw/rapid/symbol/data/RAPID/{name}", {}

    def symbol_set(self, name: str) -> tuple[str, dict[str, str]]:
        path, _ = self.symbol(name)
        return (path, {}) if self.secure else (path, {"action": "set"})

    def _action(self, base: str, action: str) -> tuple[str, dict[str, str]]:
        return (f"{base}/{action}", {}) if self.secure else (base, {"action": action})

    def mastership(self, action: str) -> tuple[str, dict[str, str]]:
        """``request`` or ``release`` (RAPID/edit domain on RW 7, all domains on RW 6)."""
        return self._action("/rw/mastership/edit" if self.secure else "/rw/mastership", action)

    def rapid(self, action: str) -> tuple[str, dict[str, str]]:
        """``start`` or ``stop`` of RAPID execution."""
        return self._action("/rw/rapid/execution", action)

    # --- bodies ----------------------------------------------------------
    def states(self, body: Any) -> list[dict[str, Any]]:
        """The list of state objects of a JSON answer."""
        try:
            states = body["state"] if self.secure else body["_embedded"]["_state"]
        except (KeyError, TypeError) as err:
            where = "state" if self.secure else "_embedded._state"
            raise ProtocolError(f"RWS {self.version}.0 answer without {where}") from err
        if not isinstance(states, list) or not all(isinstance(s, dict) for s in states):
            raise ProtocolError("RWS state is not a list of objects")
        return states

    def status(self, body: Any) -> tuple[int | None, str]:
        """Controller return code and message of an error answer (None, '' if absent)."""
        try:
            status = body["status"] if self.secure else body["_embedded"]["status"]
            return int(status["code"]), str(status.get("msg", ""))
        except (KeyError, TypeError, ValueError):
            return None, ""

    def wrap(self, states: list[dict[str, Any]], base: str = "") -> dict[str, Any]:
        """A JSON answer carrying ``states`` (used by the fake)."""
        links = {"base": {"href": base}}
        if self.secure:
            return {"_links": links, "state": states}
        return {"_links": links, "_embedded": {"_state": states}}

    def error(self, code: int, msg: str) -> dict[str, Any]:
        """A JSON error answer (used by the fake)."""
        status = {"code": code, "msg": msg}
        if self.secure:
            return {"status": status}
        return {"_links": {}, "_embedded": {"_state": [], "status": status}}


def state_value(state: dict[str, Any], key: str, kind: str) -> str:
    """``state[key]`` of a state of ``_type`` ``kind``, checked."""
    if state.get("_type") != kind:
        raise ProtocolError(f"RWS answer of type {state.get('_type')!r}, expected {kind!r}")
    if key not in state:
        raise ProtocolError(f"RWS {kind} without {key!r}")
    return str(state[key])


def joint_degrees(state: dict[str, Any]) -> np.ndarray:
    """rax_1..rax_6 (strings, deg) of an ``ms-jointtarget`` state, as floats (deg)."""
    texts = [state_value(state, f"rax_{i}", "ms-jointtarget") for i in range(1, 7)]
    try:
        return np.array([float(t) for t in texts])
    except ValueError as err:
        raise ProtocolError(f"RWS jointtarget with a non-numeric axis: {texts!r}") from err


def format_jointtarget(q_deg: np.ndarray) -> str:
    """RAPID ``jointtarget`` text of six robot axes (deg), no external axes."""
    robax = ",".join(f"{float(v):.6f}" for v in q_deg)
    return f"[[{robax}],[{','.join([NO_AXIS] * 6)}]]"


def parse_jointtarget(text: str) -> np.ndarray:
    """Robot axes (deg) of RAPID ``jointtarget`` text."""
    m = _JOINTTARGET.match(text)
    parts = m.group(1).split(",") if m else []
    try:
        if len(parts) != 6 or len(m.group(2).split(",")) != 6:
            raise ValueError
        return np.array([float(v) for v in parts])
    except ValueError:
        raise ProtocolError(f"not a RAPID jointtarget: {text[:80]!r}") from None


def format_bool(value: bool) -> str:
    return "TRUE" if value else "FALSE"


def parse_bool(text: str) -> bool:
    t = text.strip().upper()
    if t not in ("TRUE", "FALSE"):
        raise ProtocolError(f"not a RAPID bool: {text[:40]!r}")
    return t == "TRUE"
