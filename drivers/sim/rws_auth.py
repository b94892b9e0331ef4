"""Server side of the HTTP authentication of a simulated ABB controller.

RWS 1.0 (RobotWare 6): Digest, RFC 7616 with MD5 and ``qop=auth`` in realm
``validusers@robapi.abb``; RWS 2.0 (RobotWare 7): Basic. After a successful
authentication the controller sets the session cookies ``-http-session-`` and
``ABBCX``; requests that carry them are not asked to authenticate again.
"""

from __future__ import annotations

import base64
import hashlib
import re
import secrets
import threading

from drivers.rws import REALM

_PARAM = re.compile(r'(\w+)=(?:"([^"]*)"|([^,\s]*))')


def _md5(text: str) -> str:
    return hashlib.md5(text.encode("utf-8")).hexdigest()


class RwsAuth:
    """Users, nonces and sessions of one simulated controller (thread-safe)."""

    def __init__(self, users: dict[str, str], digest: bool) -> None:
        self.users = dict(users)
        self.digest = digest
        self._nonces: set[str] = set()
        self.sessions: dict[str, str] = {}  # -http-session- value -> user
        self._lock = threading.Lock()

    def challenge(self) -> str:
        """The ``WWW-Authenticate`` header of a 401 answer."""
        if not self.digest:
            return f'Basic realm="{REALM}"'
        nonce = secrets.token_hex(16)
        with self._lock:
            self._nonces.add(nonce)
        return (f'Digest realm="{REALM}", domain="/", qop="auth", nonce="{nonce}", '
                f'opaque="{secrets.token_hex(8)}", algorithm="MD5", stale="FALSE"')

    def session_user(self, cookie_header: str | None) -> str | None:
        """The user of a valid session cookie, else None."""
        if not cookie_header:
            return None
        cookies = dict(part.strip().split("=", 1) for part in cookie_header.split(";")
                       if "=" in part)
        with self._lock:
            return self.sessions.get(cookies.get("-http-session-", ""))

    def check(self, authorization: str | None, method: str, uri: str) -> str | None:
        """The authenticated user of an ``Authorization`` header, else None."""
        if not authorization:
            return None
        scheme, _, rest = authorization.partition(" ")
        if not self.digest:
            if scheme.lower() != "basic":
                return None
            try:
                user, _, password = base64.b64decode(rest).decode("utf-8").partition(":")
            except (ValueError, UnicodeDecodeError):
                return None
            return user if self.users.get(user) == password and user in self.users else None
        if scheme.lower() != "digest":
            return None
        p = {k: a or b for k, a, b in _PARAM.findall(rest)}
        user = p.get("username", "")
        with self._lock:
            known = p.get("nonce") in self._nonces
        if not known or user not in self.users or p.get("realm") != REALM \
                or p.get("qop") != "auth" or p.get("uri") != uri:
            return None
        ha1 = _md5(f"{user}:{REALM}:{self.users[user]}")
        ha2 = _md5(f"{method}:{uri}")
        expect = _md5(f"{ha1}:{p['nonce']}:{p.get('nc', '')}:{p.get('cnonce', '')}:auth:{ha2}")
        return user if secrets.compare_digest(expect, p.get("response", "")) else None

    def open_session(self, user: str) -> list[str]:
        """``Set-Cookie`` header values of a new session for ``user``."""
        sid = secrets.token_hex(12)
        with self._lock:
            self.sessions[sid] = user
        return [f"-http-session-={sid}; path=/; httponly",
                f"ABBCX={secrets.randbelow(10**6)}; path=/"]

    def end_session(self, cookie_header: str | None) -> None:
        if not cookie_header:
            return
        for part in cookie_header.split(";"):
            name, _, value = part.strip().partition("=")
            if name == "-http-session-":
                with self._lock:
                    self.sessions.pop(value, None)

    def drop_sessions(self) -> None:
        """Forget every session (the controller restarted its web server)."""
        with self._lock:
            self.sessions.clear()
            self._nonces.clear()
