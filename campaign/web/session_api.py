"""``/api/session``: what the page needs to talk to the server (the CSRF header value)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from pydantic import BaseModel

router = APIRouter(prefix="/api", tags=["session"])


class Session(BaseModel):
    """The header value POST requests must carry, the workspace's name, and whether this
    server may run acquisitions on hardware (``campaign gui --hardware``)."""

    csrf_header: str
    csrf_token: str
    workspace: str
    hardware: bool = False


@router.get("/session", response_model=Session)
def session(request: Request) -> Session:
    """The CSRF token for this server (same-origin pages only: no CORS)."""
    from campaign.web.security import CSRF_HEADER

    return Session(csrf_header=CSRF_HEADER, csrf_token=request.app.state.csrf,
                   workspace=request.app.state.workspace.name,
                   hardware=request.app.state.hardware)
