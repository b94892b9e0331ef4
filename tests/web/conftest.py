"""Fixtures of the GUI tests: a workspace with a plan, an app, an authenticated client; a
GUI server in a thread and one headless Chromium for the session (each test its own
browser context), written once for every browser test."""

from __future__ import annotations

import contextlib
import shutil
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

TOKEN = "test-token-0123456789"
#: the token of the servers the browser tests open
BROWSER_TOKEN = "browser-token-0123456789"
CHROMIUM = Path("/usr/bin/chromium")
#: the page size of every browser test (px)
VIEWPORT = {"width": 1300, "height": 1000}
#: three KR240-2 poses in its zones (model convention, deg), drawn once (seed 7)
POSES_DEG = [[-11.0, 6.0, 11.0, 70.0, 40.0, -35.0], [25.0, 22.0, -4.0, -60.0, 55.0, 20.0],
             [5.0, 15.0, 20.0, 30.0, -50.0, 80.0]]


@pytest.fixture
def workspace(tmp_path: Path) -> Path:
    """A workspace holding a small plan (3 tests of the KR240-2) and a robot file."""
    ws = tmp_path / "ws"
    (ws / "plan").mkdir(parents=True)
    from analysis.model.robots import builtin_files

    shutil.copy(builtin_files()["kr240-2"], ws / "robot.toml")
    _write_plan(ws / "plan")
    return ws


def _write_plan(d: Path) -> None:
    from campaign.planning.plan_output import COLUMNS

    shutil.copy(Path(__file__).parents[2] / "protocols" / "kr240-2.toml", d / "protocol.toml")
    poses = POSES_DEG
    rows = []
    for i, q in enumerate(poses, 1):
        row = {c: 0 for c in COLUMNS}
        row.update(test=i, pose=i, zone="z", load_case="w", method="m", repeats=1)
        for j in range(6):
            row[f"q{j + 1}_model_deg"] = q[j]
            row[f"q{j + 1}_ctrl_deg"] = q[j]
        row.update(fy_N=2200, fz_N=2200, mx_N_m=200, my_N_m=200)
        rows.append(row)
    import pandas as pd

    pd.DataFrame(rows, columns=COLUMNS).to_csv(d / "plan.csv", index=False)


@pytest.fixture(scope="session")
def acquired_kr240(tmp_path_factory) -> Path:
    """A directory holding ``plan`` (6 KR240-2 tests, 1 repeat; 400 candidates, seed 1) and
    ``run``, its acquisition on the simulated lab (the acquire job, time x 300), not
    analysed. Acquired once for the session (seeded: every acquisition of it gives the
    same numbers) and never changed: a test copies it with :func:`copy_acquired`."""
    import pandas as pd

    from campaign.jobs.acquire import AcquireJobOptions
    from campaign.jobs.acquire import run as acquire
    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    src = tmp_path_factory.mktemp("kr240-acquired")
    protocol = Path(__file__).parents[2] / "protocols" / "kr240-2.toml"
    write_plan(make_plan(load_protocol(protocol), candidates=400, seed=1, tests=6),
               src / "plan", figure=False)
    df = pd.read_csv(src / "plan" / "plan.csv", dtype={"zone": str, "load_case": str,
                                                       "method": str})
    df.assign(repeats=1).to_csv(src / "plan" / "plan.csv", index=False)
    acquire(AcquireJobOptions(plan=src / "plan", out=src / "run", fake=True, assume_yes=True,
                              time_scale=300.0), say=lambda s: None)
    assert (src / "run" / "tests.csv").is_file()
    return src


def copy_acquired(source: Path, ws: Path) -> Path:
    """``ws`` (created) holding copies of ``plan`` and ``run`` of :func:`acquired_kr240`."""
    ws.mkdir(parents=True, exist_ok=True)
    for name in ("plan", "run"):
        shutil.copytree(source / name, ws / name)
    return ws


@pytest.fixture
def app(workspace):
    from campaign.web.app import create_app

    return create_app(workspace, TOKEN)


@pytest.fixture
def client(app):
    """A TestClient holding the token cookie, with the CSRF header on every request."""
    from fastapi.testclient import TestClient

    from campaign.web.security import CSRF_HEADER, csrf_value

    c = TestClient(app)
    r = c.get(f"/?token={TOKEN}")
    assert r.status_code == 200
    c.headers[CSRF_HEADER] = csrf_value(TOKEN)
    return c


@contextlib.contextmanager
def gui_server(workspace: Path, token: str = BROWSER_TOKEN, *,
               jobs_in_threads: bool = False) -> Iterator[str]:
    """A GUI server on 127.0.0.1 (a free port) in a thread, serving ``workspace``; yields
    its URL with the token. ``jobs_in_threads``: the queue's jobs run in its threads (for
    tests of the page, not of the job processes)."""
    from campaign.web.server import GuiOptions, make_server, url_of

    srv, sock = make_server(GuiOptions(workspace=workspace, port=0, open_browser=False), token)
    if jobs_in_threads:
        srv.config.app.state.jobs_in_threads = True
    thread = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    end = time.monotonic() + 60
    while not srv.started:
        assert thread.is_alive() and time.monotonic() < end, "the GUI server did not start"
        time.sleep(0.02)
    assert sock.getsockname()[0] == "127.0.0.1"
    try:
        yield url_of(sock, token)
    finally:
        srv.should_exit = True
        thread.join(10)


@pytest.fixture
def server(workspace):
    """The URL (with its token) of a GUI server on 127.0.0.1 serving ``workspace``."""
    with gui_server(workspace) as url:
        yield url


@contextlib.contextmanager
def browser_page(browser, url: str, errors: list[str] | None = None):
    """A page of ``url`` in a new context of ``browser``; its uncaught exceptions are
    collected in ``errors`` and, when the block ends without an exception, asserted none."""
    errors = [] if errors is None else errors
    context = browser.new_context(viewport=VIEWPORT)
    try:
        page = context.new_page()
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.goto(url)
        yield page
    finally:
        context.close()
    assert not errors, errors


@pytest.fixture
def open_url(browser):
    """A function (url) -> a page of it in its own browser context; at the test's end the
    contexts are closed and no page may have raised an uncaught exception."""
    with contextlib.ExitStack() as stack:
        yield lambda url: stack.enter_context(browser_page(browser, url))


def post_followed(client, url: str, **kwargs):
    """POST ``url``; a queued job's answer (202) followed to its end and answered as
    :class:`tests.jobs.conftest.Finished` (200 and the result, or the error's status and
    record), any other answer as it came."""
    from tests.jobs.conftest import Finished, wait_job

    answer = client.post(url, **kwargs)
    if answer.status_code != 202:
        return answer
    return Finished(wait_job(client, answer.json()["id"]))
