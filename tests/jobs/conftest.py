"""Fixtures of the jobs' tests: a web app over the jobs router in a workspace, the CLI."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

fastapi = pytest.importorskip("fastapi", reason="fastapi is not installed (pip install fastapi)")
pytest.importorskip("httpx", reason="httpx is not installed (pip install httpx)")


@pytest.fixture
def ws(tmp_path) -> Path:
    """The workspace directory (the CLI runs with it as its working directory)."""
    d = tmp_path / "ws"
    d.mkdir()
    return d


class Finished:
    """The end of a queued job as a response: 200 and the result document when done, the
    error's status (400, 409) and record when it failed."""

    def __init__(self, job: dict) -> None:
        self.job = job
        error = job["error"] or {}
        self.status_code = 200 if job["state"] == "done" else error.get("status", 500)
        self.body = job["result"] if job["state"] == "done" else \
            {k: v for k, v in error.items() if k != "status"}
        self.text = json.dumps(job)

    def json(self):
        return self.body


class FollowedClient:
    """A TestClient whose POST of a queued job (202) follows the job to its end
    (GET /api/jobs/{id} until its state is final) and answers as :class:`Finished`;
    other answers are the TestClient's."""

    def __init__(self, client) -> None:
        self.raw = client

    def __getattr__(self, name):
        return getattr(self.raw, name)

    def post(self, url: str, **kwargs):
        answer = self.raw.post(url, **kwargs)
        if answer.status_code != 202:
            return answer
        return Finished(wait_job(self.raw, answer.json()["id"]))


def wait_job(client, job_id: str, timeout: float = 240.0) -> dict:
    """GET /api/jobs/{id} until the job has ended; its state."""
    import time

    end = time.monotonic() + timeout
    while time.monotonic() < end:
        job = client.get(f"/api/jobs/{job_id}").json()
        if job["state"] in ("done", "failed", "cancelled"):
            return job
        time.sleep(0.05)
    raise AssertionError(f"job {job_id} still {job['state']} after {timeout} s")


@pytest.fixture
def app(ws):
    """An app built here: the jobs routers over the workspace ``ws``."""
    from fastapi import FastAPI

    from campaign.web import api_jobs, demo_api

    app = FastAPI()
    app.state.workspace = ws
    app.state.jobs_in_threads = True  # the results are the point here, not the isolation
    app.include_router(api_jobs.router)
    app.include_router(demo_api.router)
    return app


@pytest.fixture
def client(app):
    """A TestClient on ``app`` whose POSTs of queued jobs wait for their end."""
    from fastapi.testclient import TestClient

    return FollowedClient(TestClient(app))


def cli(ws: Path, *args: str) -> subprocess.CompletedProcess:
    """``campaign ARGS`` run in the workspace ``ws`` (relative paths as the API's)."""
    return subprocess.run([sys.executable, "-m", "campaign", *args], cwd=ws,
                          capture_output=True, text=True, timeout=240, env=os.environ.copy())


def cli_json(ws: Path, *args: str) -> dict:
    proc = cli(ws, *args, "--json")
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def cli_error(ws: Path, *args: str) -> str:
    """The one line of a refused command (without 'error: '); its status must be 2.

    Run in this process (``campaign.cli.main`` in ``ws``, stderr captured): a refusal is
    decided before any work, so a process of its own (~2 s of start-up each, a dozen of
    them) would add nothing the line or the status shows; ``cli`` keeps the subprocess
    for the commands that do the work, and tests/cli the CLI's own exit paths."""
    import contextlib
    import io

    from campaign.cli import main

    err = io.StringIO()
    with contextlib.chdir(ws), contextlib.redirect_stderr(err), \
            contextlib.redirect_stdout(io.StringIO()):
        status = main(list(args))
    text = err.getvalue()
    assert status == 2, (status, text)
    assert "Traceback" not in text, text
    lines = text.strip().splitlines()
    assert len(lines) == 1, text
    return lines[0].removeprefix("error: ")


@pytest.fixture
def campaigns(ws, analyses) -> tuple[str, str]:
    """The two analyses copied into the workspace: their relative paths."""
    import shutil

    for src in analyses:
        shutil.copytree(src, ws / src.name)
    return tuple(src.name for src in analyses)
