"""Starting the GUI server: bind the socket, print the URL with its token, serve.

The socket is bound before uvicorn starts, so that a port in use is one clear
line and ``--port 0`` (any free port) still prints the right URL.
"""

from __future__ import annotations

import socket
import threading
import webbrowser
from dataclasses import dataclass
from pathlib import Path

from analysis.errors import InputError

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765


@dataclass(frozen=True)
class GuiOptions:
    """How to serve: workspace directory, address, remote access (password) and HTTPS
    (certfile/keyfile, PEM; remote access without them: a self-signed certificate);
    hardware: acquisitions may drive a real robot; scheduler: the placement search's Dask
    scheduler (None: a local cluster);
    ledger: the fleet ledger's URL (None: STIFFNESS_CAMPAIGN_DB, else none)."""

    workspace: Path
    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    open_browser: bool = True
    allow_remote: bool = False
    password: str | None = None
    certfile: Path | None = None
    keyfile: Path | None = None
    hardware: bool = False
    scheduler: str | None = None
    ledger: str | None = None


def bind(host: str, port: int) -> socket.socket:
    """A listening TCP socket on (host, port); InputError when the address is taken."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    try:
        sock.bind((host.strip("[]"), port))
    except OSError as err:
        sock.close()
        raise InputError(f"cannot listen on {host}:{port} ({err.strerror}); choose another "
                         "--port (0: any free port)", where="--port") from err
    sock.listen(64)
    sock.set_inheritable(True)
    return sock


def url_of(sock: socket.socket, token: str, tls: bool = False) -> str:
    """The address to open, with the access token (https when ``tls``)."""
    host, port = sock.getsockname()[:2]
    shown = f"[{host}]" if ":" in host else host
    return f"{'https' if tls else 'http'}://{shown}:{port}/?token={token}"


def make_server(options: GuiOptions, token: str):
    """(uvicorn.Server, bound socket) for ``options`` (see :func:`prepare`)."""
    prepared = prepare(options, token)
    return prepared.server, prepared.sock


@dataclass
class Prepared:
    """A server ready to run: uvicorn's server, its bound socket, and its certificate
    (:class:`campaign.web.tls.ServerCertificate`; None: plain HTTP on loopback)."""

    server: object
    sock: socket.socket
    cert: object | None


def prepare(options: GuiOptions, token: str) -> Prepared:
    """The server of ``options``; refuses a non-loopback host without --allow-remote and
    a password, and serves remote access over HTTPS only."""
    import uvicorn

    from campaign.web.app import create_app
    from campaign.web.security import check_bind, is_loopback
    from campaign.web.tls import server_certificate

    if not 0 <= options.port <= 65535:
        raise InputError(f"expected 0 to 65535, got {options.port}", where="--port")
    check_bind(options.host, options.allow_remote, options.password)
    cert = server_certificate(options.host, options.allow_remote, options.certfile,
                              options.keyfile)
    if cert is None and not is_loopback(options.host):  # check_bind lets none through
        raise InputError("a non-loopback address is served over HTTPS only", where="--host")
    sock = bind(options.host, options.port)
    try:
        app = create_app(options.workspace, token, options.password if options.allow_remote
                         else None, hardware=options.hardware,
                         scheduler=options.scheduler, ledger=options.ledger)
    except BaseException:
        sock.close()
        raise
    # the context made here (in memory for a self-signed certificate) is uvicorn's
    factory = None if cert is None else (lambda config, default: cert.context)
    config = uvicorn.Config(app, log_level="warning", access_log=False, lifespan="off",
                            ssl_context_factory=factory)
    return Prepared(uvicorn.Server(config), sock, cert)


def serve(options: GuiOptions, token: str, announce) -> None:
    """Serve until Ctrl-C; ``announce(url, cert)`` is called once the socket listens
    (``cert``: the :class:`campaign.web.tls.ServerCertificate`, None for plain HTTP)."""
    prepared = prepare(options, token)
    server, sock, cert = prepared.server, prepared.sock, prepared.cert
    url = url_of(sock, token, tls=cert is not None)
    announce(url, cert)
    if options.open_browser:
        threading.Timer(0.5, webbrowser.open, args=(url,)).start()
    server.run(sockets=[sock])
