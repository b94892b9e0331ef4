"""Who may talk to the GUI server and which files it may touch.

* Access token (as Jupyter does): the URL the server prints carries
  ``?token=...``; the first request with it sets an HttpOnly, SameSite=Strict
  cookie, and every later request must carry the cookie (or the header
  ``Authorization: token ...``). Without it: 401 (403 for a wrong token).
* Cross-site request forgery: a state-changing request (any method but GET,
  HEAD, OPTIONS) also needs the header ``X-CSRF-Token``, a value derived from the
  token that the page reads from ``/api/session`` (same-origin only: no CORS).
* Binding: loopback by default; another address only with ``allow_remote`` and a
  password (then ``/login`` takes the password instead of the token), over HTTPS
  only (:mod:`campaign.web.tls`: the operator's certificate or a self-signed one).
* Files: :func:`inside_workspace` resolves a path given by a client and refuses
  absolute paths, ``..``, and symbolic links anywhere under the workspace.
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from pathlib import Path, PurePosixPath

from analysis.errors import InputError

COOKIE = "campaign_gui_token"
CSRF_HEADER = "X-CSRF-Token"
SAFE_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})


def new_token() -> str:
    """A fresh random access token (URL-safe, 256 bits)."""
    return secrets.token_urlsafe(32)


def csrf_value(token: str) -> str:
    """The header value state-changing requests must carry (derived from the token)."""
    return hmac.new(token.encode(), b"csrf", hashlib.sha256).hexdigest()


def same(a: str | None, b: str) -> bool:
    """Constant-time comparison of a client's value with the expected one."""
    return a is not None and hmac.compare_digest(a.encode(), b.encode())


def is_loopback(host: str) -> bool:
    """True for localhost and loopback addresses (127.0.0.0/8, ::1): the drivers' test."""
    from drivers.loopback_guard import is_loopback_host

    return is_loopback_host(host)


def check_bind(host: str, allow_remote: bool, password: str | None) -> None:
    """Refuse a non-loopback ``host`` unless ``allow_remote`` and a password are given.

    ``allow_remote`` is remote mode whatever the host (a loopback address may be
    forwarded): it always needs the password, and the server then speaks only HTTPS
    (:mod:`campaign.web.tls`)."""
    if not allow_remote and is_loopback(host):
        return
    if not allow_remote:
        raise InputError(f"{host} is not a loopback address: the GUI would be reachable "
                         "from the network; add --allow-remote and --password", where="--host")
    if not password:
        raise InputError("--allow-remote needs a --password", where="--password")
    if len(password) < 8:
        raise InputError("use a password of at least 8 characters", where="--password")


def inside_workspace(workspace: Path, relative: str, where: str = "path") -> Path:
    """``relative`` resolved under ``workspace``; InputError for ``..``, absolute paths,
    symbolic links on the way, or a path that leaves the workspace."""
    text = str(relative).replace("\\", "/")
    if not text or "\x00" in text:
        raise InputError("empty or invalid path", where=where)
    pure = PurePosixPath(text)
    if pure.is_absolute() or text.startswith("~") or (len(text) > 1 and text[1] == ":"):
        raise InputError("an absolute path is refused: give a path inside the workspace",
                         where=where)
    if ".." in pure.parts:
        raise InputError("'..' is refused: give a path inside the workspace", where=where)
    root = workspace.resolve()
    path = root
    try:
        for part in pure.parts:
            if part in ("", "."):
                continue
            path = path / part
            if path.is_symlink():
                raise InputError("a symbolic link is refused", where=where)
        inside = path.resolve().is_relative_to(root)
    except OSError as err:  # a name too long, a loop: not a path of the workspace
        raise InputError(f"not a usable path ({err.strerror})", where=where) from err
    if not inside:
        raise InputError("the path leaves the workspace", where=where)
    return path
