"""``/api/analyze``: the Analyze view's server side (the analyze job on a workspace run).

``POST /api/analyze/run`` runs :func:`campaign.jobs.analyze.run` on a run directory of
the workspace with a method, a robust fit, ``force`` (re-analysis) and ``accept_misfit``
(keep a refused result; results.json and the report say so, as with the CLI's
``--accept-misfit``). The answer carries the report's verdict line and k with its 95 %
interval (N m/rad; the page shows kN m/rad); a refusal is 400 with its reasons listed.
"""

from __future__ import annotations

from pathlib import Path

from fastapi import APIRouter, Request
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field

router = APIRouter(prefix="/api/analyze", tags=["analyze"])
REFUSED = "refused, the data do not support this stiffness: "


class AnalyzeRequest(BaseModel):
    """run_dir: the run directory, relative to the workspace."""

    run_dir: str = Field(..., min_length=1, max_length=1000)
    method: str = Field("ols", pattern="^(ols|wls|exact)$")
    robust: str = Field("none", pattern="^(none|huber|tukey)$")
    force: bool = False
    accept_misfit: bool = False
    report: bool = True


def refusal_reasons(text: str) -> list[str]:
    """The reasons of a refusal message of the analyze job (one per ``|`` part)."""
    body = text.split(REFUSED, 1)[1]
    body = body.split("; to keep the result anyway", 1)[0]
    return [r.strip() for r in body.split(" | ") if r.strip()]


@router.post("/run")
def analyze_run(request: Request, body: AnalyzeRequest):
    """Analyse ``run_dir`` into ``run_dir/analysis``; verdict, k, intervals and files."""
    from analysis.errors import InputError
    from analysis.report.verdict import verdict
    from campaign.jobs.analyze import AnalyzeOptions, run
    from campaign.jobs.choices import Method, Robust, json_ready
    from campaign.web.job_errors import describe
    from campaign.web.security import inside_workspace

    ws = Path(request.app.state.workspace)
    options = None
    try:
        run_dir = inside_workspace(ws, body.run_dir, "run_dir")
        if not run_dir.is_dir():
            raise InputError("no such run directory in the workspace", where="run_dir")
        options = AnalyzeOptions(run_dir=run_dir, method=Method(body.method),
                                 robust=Robust(body.robust), force=body.force,
                                 accept_misfit=body.accept_misfit, report=body.report,
                                 ledger=getattr(request.app.state, "ledger", None))
        result = run(options)
    except InputError as err:
        text = str(err).replace(f"{ws}/", "")
        reasons = refusal_reasons(text) if REFUSED in text else []
        # field and options as campaign.web.job_errors gives them: the page says the
        # command-line options it names (--force) by its own labels
        named = describe(err, ws, options) or {}
        return JSONResponse({"detail": text, "refused": reasons, "field": named.get("field"),
                             "options": named.get("options", {})}, status_code=400)
    except FileExistsError as err:
        return JSONResponse({"detail": str(err).replace(f"{ws}/", ""), "refused": []},
                            status_code=409)
    # the run's own notes (partial run, failed rows) are shown beside it from analysis.json
    v = verdict(result.identification, [])
    r = result.results
    joints = [{"joint": j, "k_Nm_per_rad": k, "ci95_Nm_per_rad": ci, "se_Nm_per_rad": se}
              for j, k, ci, se in zip(r["joints_identified"], r["joint_stiffness_Nm_per_rad"],
                                      r["ci95_Nm_per_rad"], r["standard_error_Nm_per_rad"],
                                      strict=True)]
    files = {name: str(Path(p).resolve().relative_to(ws.resolve()))
             for name, p in result.files.items() if Path(p).is_file()}
    return JSONResponse(json_ready({
        "verdict": {"kind": v.kind, "text": v.text}, "joints": joints,
        "method": r.get("method"), "robust": r.get("robust"),
        "misfit_accepted": r.get("misfit_accepted"), "files": files,
        "run": {k: result.summary.get(k) for k in ("status", "partial", "failed_rows")}}))
