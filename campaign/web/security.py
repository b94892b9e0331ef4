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
  absolute paths, ``..``, and symbolic links anywhere under the workspace: the one
  path rule of every route (:func:`campaign.web.api_jobs.inside` answers its refusal as 400).
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


def inside_workspace(workspace: Path, relative: str | Path, where: str = "path") -> Path:
    """``relative`` (a path relative to ``workspace``) as an absolute path inside it: the one
    path rule of the web face, for every path field of every form and route.

    InputError (one line) for an empty path, a NUL character, an absolute path (``/x``,
    ``~x``, ``C:x``), a ``..`` part, a name longer than 255 bytes, a symbolic link
    anywhere on the way (one leading inside is refused as well: what it points to can
    change between the check and the use), and a path that otherwise resolves out of the
    workspace. The path itself need not exist (an output to create)."""
    text = str(relative).replace("\\", "/")
    if not text or "\x00" in text:
        raise InputError("empty or invalid path (a NUL character)", where=where)
    pure = PurePosixPath(text)
    if pure.is_absolute() or text.startswith("~") or ":" in (pure.parts or ("",))[0]:
        raise InputError(f"{text!r} is an absolute path, refused: give a path inside the "
                         "workspace", where=where)
    if ".." in pure.parts:
        raise InputError(f"{text!r} has a '..' part, refused: give a path inside the "
                         "workspace", where=where)
    if any(len(part.encode()) > 255 for part in pure.parts):
        raise InputError("a name in the path is longer than 255 bytes", where=where)
    root = Path(workspace).resolve()
    path = root
    try:
        for part in pure.parts:
            if part in ("", "."):
                continue
            path = path / part
            if path.is_symlink():
                raise InputError(f"{path.relative_to(root)} is a symbolic link, refused (a "
                                 "link leads out of the workspace as easily as within it)",
                                 where=where)
        inside = path.resolve().is_relative_to(root)
    except (OSError, RuntimeError) as err:  # a name too long, a loop: not a workspace path
        why = getattr(err, "strerror", None) or str(err)
        raise InputError(f"not a usable path ({why})", where=where) from err
    if not inside:
        raise InputError("the path leaves the workspace", where=where)
    return path
