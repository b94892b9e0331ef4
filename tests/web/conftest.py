"""Fixtures of the GUI tests: a workspace with a plan, an app, an authenticated client."""

from __future__ import annotations

import shutil
import threading
import time
from pathlib import Path

import pytest

TOKEN = "test-token-0123456789"
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


@pytest.fixture
def server(workspace):
    """(base URL, token) of a GUI server on 127.0.0.1 serving ``workspace``."""
    from campaign.web.server import GuiOptions, make_server, url_of

    token = "browser-token-0123456789"
    srv, sock = make_server(GuiOptions(workspace=workspace, port=0, open_browser=False), token)
    thread = threading.Thread(target=srv.run, kwargs={"sockets": [sock]}, daemon=True)
    thread.start()
    for _ in range(200):
        if srv.started:
            break
        time.sleep(0.02)
    assert sock.getsockname()[0] == "127.0.0.1"
    yield url_of(sock, token)
    srv.should_exit = True
    thread.join(10)
