"""``/api/runs``: the Runs view (every plan, run and analysis in the workspace; read-only).

JSON for scripts and the page's tests; ``/api/runs/table`` is the same list as an
HTML table fragment, which the page loads with htmx.
"""

from __future__ import annotations

from html import escape
from urllib.parse import quote

from fastapi import APIRouter, Query, Request
from fastapi.responses import FileResponse, HTMLResponse
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
    files: list[str]


#: what /api/runs/file serves, by suffix (read-only; nothing else of the workspace)
MEDIA = {".html": "text/html", ".pdf": "application/pdf", ".png": "image/png",
         ".txt": "text/plain", ".json": "application/json", ".toml": "text/plain",
         ".csv": "text/csv"}
MAX_FILE_BYTES = 200_000_000


@router.get("/file")
def run_file(request: Request, path: str = Query(..., max_length=1000)) -> FileResponse:
    """One file of a plan, run or analysis (a report, a summary, results.json), by its
    path inside the workspace; ``..``, absolute paths and symbolic links are refused."""
    from analysis.errors import InputError
    from campaign.web.security import inside_workspace

    p = inside_workspace(request.app.state.workspace, path, "path")
    media = MEDIA.get(p.suffix.lower())
    if media is None:
        raise InputError(f"only {', '.join(sorted(MEDIA))} files are served", where="path")
    if not p.is_file():
        raise InputError("no such file in the workspace", where="path")
    if p.stat().st_size > MAX_FILE_BYTES:
        raise InputError("file too large to serve", where="path")
    # a report opened from the page must not run scripts with the page's rights
    return FileResponse(p, media_type=media, headers={
        "Content-Security-Policy": "sandbox; default-src 'none'; img-src data:; "
                                   "style-src 'unsafe-inline'"} if media == "text/html" else None)


@router.get("", response_model=list[RunEntry])
def runs(request: Request) -> list[dict]:
    """Plans, runs and analyses in the workspace, newest first."""
    from campaign.jobs.runs import as_dicts, list_workspace

    return as_dicts(list_workspace(request.app.state.workspace))


def _k_text(k: list[dict]) -> str:
    """'k1 = 1409.8 [1396.0, 1423.6]; ...' (kN m/rad): an analysis' k and interval, a
    plan's prior and predicted se."""
    from analysis.report.formatting import interval_kNm, k_kNm, sig

    parts = []
    for row in k:
        v = row.get("k_Nm_per_rad")
        if not isinstance(v, int | float):
            continue
        # the report's k format (kN m/rad, 5 significant digits; no thousands separator,
        # which would read as a list separator inside an interval)
        text = f"k{row.get('joint')} = {k_kNm(v)}"
        se, ci = row.get("se_Nm_per_rad"), row.get("ci95_Nm_per_rad")
        if isinstance(se, int | float):
            text += f" \u00b1 {sig(se / 1e3, 2, zeros=True)}"
        elif isinstance(ci, list) and len(ci) == 2 and all(isinstance(c, int | float)
                                                           for c in ci):
            text += f" {interval_kNm(*ci)}"
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
            f"<td class='k'>{escape(_k_text(e.k))}</td><td class='files'>"
            + " ".join(f"<a href='/api/runs/file?path={quote(f)}' target='_blank' "
                       f"rel='noopener'>{escape(f.rsplit('/', 1)[-1])}</a>" for f in e.files)
            + "</td></tr>")
    if not rows:
        rows.append("<tr><td colspan=8>no plan, run or analysis in the workspace yet</td></tr>")
    head = ("<tr><th>kind</th><th>path</th><th>robot</th><th>date (UTC)</th><th>status</th>"
            "<th>detail</th><th>k (kN m/rad)</th><th>files</th></tr>")
    return HTMLResponse(f"<table id='runs-table'><thead>{head}</thead><tbody>"
                        + "".join(rows) + "</tbody></table>")
