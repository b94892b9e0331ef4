"""``/api/fleet``: the Fleet view (the fleet ledger the server was started with; read-only).

``GET /api/fleet``: the robots with their last campaign and status;
``GET /api/fleet/robot?robot=ID``: one robot's campaigns (k per joint with 95 %
intervals, the change against the reference), the drift test and its alarms, and
per campaign a link to its report when its files are inside the workspace. The
ledger is ``campaign gui --db`` or ``STIFFNESS_CAMPAIGN_DB``; without one the view
says so. The work is :mod:`campaign.jobs.history`.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, Query, Request

router = APIRouter(prefix="/api/fleet", tags=["fleet"])


def _ledger(request: Request) -> str | None:
    return getattr(request.app.state, "ledger", None)


def _link(workspace: Path, source_dir: str) -> str | None:
    """Workspace-relative path of a campaign's report (else its results.json), or None when
    its files are not in the workspace (the server serves nothing else)."""
    folder = Path(source_dir)
    for name in ("report.html", "results.json"):
        p = folder / name
        try:
            rel = p.resolve().relative_to(workspace.resolve())
        except ValueError:
            return None
        if p.is_file():
            return str(rel)
    return None


@router.get("")
def fleet_robots(request: Request) -> dict:
    """Every robot of the ledger with its last campaign and status."""
    from campaign.jobs.history import fleet

    db = _ledger(request)
    if db is None:
        return {"configured": False, "robots": []}
    return {"configured": True, **fleet(db).to_json()}


@router.get("/robot")
def fleet_robot(request: Request, robot: str = Query(..., min_length=1, max_length=200)) -> dict:
    """One robot: campaigns oldest first with k and intervals, the drift test, alarms."""
    from analysis.errors import InputError
    from campaign.jobs.history import robot_view

    db = _ledger(request)
    if db is None:
        raise InputError("no fleet ledger: start campaign gui with --db URL or set "
                         "STIFFNESS_CAMPAIGN_DB", where="campaign gui")
    view = robot_view(db, robot)
    ws = Path(request.app.state.workspace)
    for c in view["campaigns"]:
        c["report"] = _link(ws, c.pop("source_dir"))
    return view
