"""``/api/runs``: the Runs view (every plan, run and analysis in the workspace; read-only).

JSON for scripts and the page's tests; ``/api/runs/table`` is the same list as an
HTML table fragment, which the page loads with htmx.
"""

from __future__ import annotations

from html import escape

from fastapi import APIRouter, Request
from fastapi.responses import HTMLResponse
from pydantic import BaseModel

router = APIRouter(prefix="/api/runs", tags=["runs"])


class RunEntry(BaseModel):
    kind: str
    path: str
    robot: str
    date_utc: str
    status: str
    detail: str
    k: list[dict]


@router.get("", response_model=list[RunEntry])
def runs(request: Request) -> list[dict]:
    """Plans, runs and analyses in the workspace, newest first."""
    from campaign.jobs.runs import as_dicts, list_workspace

    return as_dicts(list_workspace(request.app.state.workspace))


def _k_text(k: list[dict]) -> str:
    parts = []
    for row in k:
        v = row.get("k_Nm_per_rad")
        if not isinstance(v, int | float):
            continue
        text = f"k{row.get('joint')} = {v / 1e3:,.0f}"
        se, ci = row.get("se_Nm_per_rad"), row.get("ci95_Nm_per_rad")
        if isinstance(se, int | float):
            text += f" \u00b1 {se / 1e3:,.1f}"
        elif isinstance(ci, list) and len(ci) == 2 and all(isinstance(c, int | float)
                                                           for c in ci):
            text += f" [{ci[0] / 1e3:,.0f}, {ci[1] / 1e3:,.0f}]"
        parts.append(text)
    return "; ".join(parts)


@router.get("/table", response_class=HTMLResponse)
def runs_table(request: Request) -> HTMLResponse:
    """The list as an HTML table (k in kN m/rad: a plan's prior \u00b1 predicted se, an
    analysis' k [95 % interval])."""
    from campaign.jobs.runs import list_workspace

    rows = []
    for e in list_workspace(request.app.state.workspace):
        rows.append(
            f"<tr data-kind='{escape(e.kind)}' data-path='{escape(e.path)}'>"
            f"<td>{escape(e.kind)}</td><td>{escape(e.path or '.')}</td>"
            f"<td>{escape(e.robot)}</td><td>{escape(e.date_utc)}</td>"
            f"<td class='status'>{escape(e.status)}</td><td>{escape(e.detail)}</td>"
            f"<td class='k'>{escape(_k_text(e.k))}</td></tr>")
    if not rows:
        rows.append("<tr><td colspan=7>no plan, run or analysis in the workspace yet</td></tr>")
    head = ("<tr><th>kind</th><th>path</th><th>robot</th><th>date (UTC)</th><th>status</th>"
            "<th>detail</th><th>k (kN m/rad)</th></tr>")
    return HTMLResponse(f"<table id='runs-table'><thead>{head}</thead><tbody>"
                        + "".join(rows) + "</tbody></table>")
