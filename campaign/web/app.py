"""The GUI's FastAPI application: the page, its JSON API and the access checks.

:func:`create_app` builds it for one workspace (the directory every file the
server reads or writes must be inside) and one access token (see
:mod:`campaign.web.security`). The API routers are the modules named in
:data:`ROUTERS`, imported when the app is built; a module that cannot be
imported is skipped with a warning, so that one face missing does not take the
others down. The OpenAPI document is at ``/openapi.json`` (the page reads its
routes from it); the interactive docs are off, since they load from a CDN. A request
body over :data:`MAX_BODY_BYTES` is answered 413 unread.
"""


import importlib  # no "from __future__ import annotations": FastAPI reads the hints
import logging
import os
import threading
from pathlib import Path

from analysis.errors import InputError

#: API routers, ``module`` with an attribute ``router`` (a fastapi.APIRouter)
ROUTERS: tuple[str, ...] = (
    "campaign.web.session_api",
    "campaign.web.sensitivity_api",
    "campaign.web.runs_api",
    "campaign.web.api_jobs",
    "campaign.web.demo_api",
    "campaign.web.use_api",
    "campaign.web.use_path_api",
    "campaign.web.acquire_api",
    "campaign.web.acquire_map_api",
    "campaign.web.plan_api",
    "campaign.web.robots_api",
    "campaign.web.analyze_plots_api",
    "campaign.web.fleet_api",
)

#: bytes of a request body at most (16 MiB; the largest legitimate body is a URDF
#: upload, 1 MB of text, or a path upload, 2 MB, JSON-escaped): FastAPI's own limit
#: answers 413 when the announced length is over it, before the body is read, and stops
#: reading a body sent without its length as soon as it passes it
MAX_BODY_BYTES = 16 * 1024 * 1024
STATIC = Path(__file__).parent / "static"
#: uPlot and htmx set inline styles; scripts only from the server's own files
CSP = ("default-src 'self'; script-src 'self'; style-src 'self' 'unsafe-inline'; "
       "img-src 'self' data:; frame-ancestors 'none'; base-uri 'none'; form-action 'self'")
log = logging.getLogger("campaign.gui")


def _routers():
    for name in ROUTERS:
        try:
            yield importlib.import_module(name).router
        except ImportError as err:
            log.warning("GUI: %s not available (%s); its views are off", name, err)


def create_app(workspace: str | Path, token: str, password: str | None = None,
               hardware: bool = False, scheduler: str | None = None,
               ledger: str | None = None):
    """The FastAPI app serving ``workspace`` to clients holding ``token`` (or ``password``).

    ``hardware``: the Acquire view may run on a real robot (the operator's ``--hardware``
    at start; each run still needs its confirmation, limits and dry run); without it the
    server runs acquisitions on the simulated lab only. ``scheduler``: the Dask scheduler
    of the placement search (the operator's ``--scheduler``; None: a local cluster); no
    request can name another. ``ledger``: the fleet ledger's URL
    (None: the STIFFNESS_CAMPAIGN_DB environment variable; neither: no Fleet view, and
    analyses are recorded nowhere).

    Raises InputError when the workspace is not an existing directory.
    """
    from fastapi import FastAPI, Request
    from fastapi.exceptions import RequestValidationError
    from fastapi.responses import FileResponse, JSONResponse, RedirectResponse
    from fastapi.staticfiles import StaticFiles

    from analysis.kinetostatics.equilibrium import EquilibriumError
    from campaign.web import security

    ws = Path(workspace)
    if not ws.is_dir():
        raise InputError("not an existing directory", where=str(ws))
    if ws.is_symlink():
        raise InputError("the workspace is a symbolic link: give the directory itself",
                         where=str(ws))
    app = FastAPI(title="campaign gui", version="1", docs_url=None, redoc_url=None,
                  max_body_size=MAX_BODY_BYTES,
                  description="The JSON API of the stiffness-campaign GUI. Every request "
                  "needs the access token (cookie or `Authorization: token ...`); "
                  f"POST requests also the `{security.CSRF_HEADER}` header. A request body "
                  f"over {MAX_BODY_BYTES} bytes is refused (413).")
    app.state.workspace = ws.resolve()
    app.state.token = token
    app.state.csrf = security.csrf_value(token)
    app.state.password = password
    app.state.hardware = bool(hardware)
    app.state.scheduler = scheduler
    from campaign.jobs.history import configured_ledger

    app.state.ledger = configured_ledger(ledger)
    # Monte-Carlo requests of every tab and client share the CPUs: one per core at a time
    app.state.compute_slots = threading.BoundedSemaphore(os.cpu_count() or 1)

    def _denied(status: int, why: str) -> JSONResponse:
        return JSONResponse({"detail": why}, status_code=status)

    @app.middleware("http")
    async def check_access(request: Request, call_next):
        url_token = request.query_params.get("token")
        header = request.headers.get("authorization", "")
        offered = (url_token or request.cookies.get(security.COOKIE)
                   or (header[6:].strip() if header.lower().startswith("token ") else None))
        login = request.url.path == "/login" and password is not None
        if not login:
            if offered is None:
                return _denied(401, "no access token: open the URL `campaign gui` printed")
            if not security.same(offered, token):
                # a restarted server has a new token: a page left open says what to do
                return _denied(403, "wrong access token (the server was restarted? open "
                               "the URL `campaign gui` printed)")
            if request.method not in security.SAFE_METHODS and not security.same(
                    request.headers.get(security.CSRF_HEADER), app.state.csrf):
                return _denied(403, f"missing or wrong {security.CSRF_HEADER} header")
        if url_token is not None and request.method == "GET" and not login:
            # as Jupyter: the URL's token becomes a cookie, and the token leaves the URL
            response = RedirectResponse(request.url.remove_query_params("token"),
                                        status_code=303)
            _set_cookie(response, token, secure=request.url.scheme == "https")
            return response
        response = await call_next(request)
        # the page's own files only; no framing by another site (clickjacking)
        response.headers.setdefault("Content-Security-Policy", CSP)
        response.headers.setdefault("X-Frame-Options", "DENY")
        response.headers.setdefault("X-Content-Type-Options", "nosniff")
        return response

    # outermost: a body over the limit is refused before it is read (413)

    @app.exception_handler(InputError)
    async def input_error(request: Request, err: InputError):
        # paths as the client gave them: relative to the workspace, not the server's disk
        root = f"{app.state.workspace}{os.sep}"
        return JSONResponse({"detail": str(err).replace(root, ""),
                             "where": None if err.where is None else
                             str(err.where).replace(root, "")}, status_code=422)

    @app.exception_handler(EquilibriumError)
    async def equilibrium_error(request: Request, err: EquilibriumError):
        return JSONResponse({"detail": str(err)}, status_code=422)

    @app.exception_handler(RequestValidationError)
    async def validation_error(request: Request, err: RequestValidationError):
        from campaign.web.validation_text import refusal

        return JSONResponse(refusal(list(err.errors())), status_code=422)

    @app.get("/", include_in_schema=False)
    def index():
        return FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-store"})

    if password is not None:
        _add_login(app, password, token)
    app.mount("/static", StaticFiles(directory=STATIC), name="static")
    for router in _routers():
        app.include_router(router)
    return app


def _set_cookie(response, token: str, secure: bool = False) -> None:
    """The access cookie; ``secure`` (over HTTPS): the browser never sends it in clear."""
    from campaign.web.security import COOKIE

    response.set_cookie(COOKIE, token, httponly=True, samesite="strict", path="/",
                        secure=secure)


def _add_login(app, password: str, token: str) -> None:
    """``/login``: a password form for remote use; the right password sets the cookie."""
    from urllib.parse import parse_qs

    from fastapi import Request
    from fastapi.responses import HTMLResponse, RedirectResponse

    from campaign.web.security import same

    form = ("<!doctype html><title>campaign gui</title><form method=post action=/login>"
            "<label>Password <input type=password name=password autofocus></label>"
            "<button>Open</button></form>")

    @app.get("/login", include_in_schema=False)
    def login_page():
        return HTMLResponse(form)

    @app.post("/login", include_in_schema=False)
    async def login(request: Request):
        # a form of one field: parsed here (FastAPI's Form needs python-multipart)
        given = parse_qs((await request.body())[:4096].decode("utf-8", "replace"))
        if not same((given.get("password") or [""])[0], password):
            return HTMLResponse(form + "<p>wrong password</p>", status_code=403)
        response = RedirectResponse("/", status_code=303)
        _set_cookie(response, token, secure=request.url.scheme == "https")
        return response
