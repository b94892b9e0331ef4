"""The GUI binds loopback by default and refuses another address without a password."""

from __future__ import annotations

import inspect

import pytest

from analysis.errors import InputError


def test_default_host_is_loopback():
    from campaign.web.security import is_loopback
    from campaign.web.server import DEFAULT_HOST, GuiOptions

    assert GuiOptions(workspace=".").host == DEFAULT_HOST == "127.0.0.1"
    assert is_loopback(DEFAULT_HOST)
    from campaign.cli.commands import gui

    assert '"127.0.0.1"' in inspect.getsource(gui)


def test_server_socket_is_loopback(tmp_path):
    from campaign.web.server import GuiOptions, make_server

    server, sock = make_server(GuiOptions(workspace=tmp_path, port=0), "t" * 20)
    try:
        assert sock.getsockname()[0] == "127.0.0.1"
    finally:
        sock.close()


@pytest.mark.parametrize("host,remote,password,ok", [
    ("127.0.0.1", False, None, True), ("::1", False, None, True),
    ("localhost", False, None, True), ("0.0.0.0", False, None, False),
    ("0.0.0.0", True, None, False), ("192.168.1.5", True, "short", False),
    ("0.0.0.0", True, "a-long-password", True), ("example.org", False, None, False),
])
def test_check_bind(host, remote, password, ok):
    from campaign.web.security import check_bind

    if ok:
        check_bind(host, remote, password)
    else:
        with pytest.raises(InputError):
            check_bind(host, remote, password)


def test_cli_refuses_remote_host_with_one_line(tmp_path):
    import subprocess
    import sys

    r = subprocess.run([sys.executable, "-m", "campaign", "gui", "--workspace", str(tmp_path),
                        "--host", "0.0.0.0", "--no-browser"], capture_output=True, text=True,
                       timeout=60)
    assert r.returncode == 2 and "--host" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_password_login(tmp_path):
    from fastapi.testclient import TestClient

    from campaign.web.app import create_app

    c = TestClient(create_app(tmp_path, "t" * 20, password="a-long-password"))
    assert c.get("/api/runs").status_code == 401
    assert c.post("/login", data={"password": "wrong"}).status_code == 403
    assert c.post("/login", data={"password": "a-long-password"}).status_code == 200
    assert c.get("/api/runs").status_code == 200


def test_campaign_gui_serves_loopback_with_its_token(tmp_path):
    """The command as a user runs it: prints a 127.0.0.1 URL; the token opens it."""
    import subprocess
    import sys
    import urllib.error
    import urllib.request

    proc = subprocess.Popen([sys.executable, "-m", "campaign", "gui", "--workspace",
                             str(tmp_path), "--port", "0", "--no-browser"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        url = next(line.split()[1] for line in proc.stdout if line.startswith("open http"))
        base, token = url.split("/?token=")
        assert base.startswith("http://127.0.0.1:") and len(token) >= 40
        with pytest.raises(urllib.error.HTTPError) as err:
            urllib.request.urlopen(base + "/api/runs", timeout=30)
        assert err.value.code == 401
        req = urllib.request.Request(base + "/api/runs",
                                     headers={"Authorization": f"token {token}"})
        with urllib.request.urlopen(req, timeout=30) as r:
            assert r.status == 200 and r.read() == b"[]"
    finally:
        proc.terminate()
        proc.wait(10)


def test_package_data_ships_the_page():
    """Every file of campaign/web/static matches a package-data glob (pip install ships it)."""
    import fnmatch
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    globs = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["campaign"]
    static = root / "campaign" / "web" / "static"
    files = [p.relative_to(root / "campaign").as_posix() for p in static.rglob("*")
             if p.is_file()]
    assert {"web/static/index.html", "web/static/vendor/uPlot.iife.min.js"} <= set(files)
    for f in files:
        assert any(fnmatch.fnmatch(f, g) and f.count("/") == g.count("/") for g in globs), f


@pytest.mark.parametrize("args,word", [
    (["--workspace", "{tmp}/missing"], "not an existing directory"),
    (["--port", "70000"], "--port"),
    (["--port", "{busy}"], "cannot listen"),
])
def test_cli_bad_options_are_one_line(tmp_path, args, word):
    import socket
    import subprocess
    import sys

    busy = socket.socket()
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    try:
        args = [a.format(tmp=tmp_path, busy=busy.getsockname()[1]) for a in args]
        if "--workspace" not in args:
            args += ["--workspace", str(tmp_path)]
        r = subprocess.run([sys.executable, "-m", "campaign", "gui", "--no-browser", *args],
                           capture_output=True, text=True, timeout=60)
    finally:
        busy.close()
    assert r.returncode == 2 and word in r.stderr, r.stderr
    errors = [line for line in r.stderr.splitlines() if line.startswith("error:")]
    assert "Traceback" not in r.stderr and len(errors) == 1 and word in errors[0]
