"""The ledger under stress: two stations adding at once, a process killed mid-add, an old
schema, bad input. Each on SQLite and on a throwaway PostgreSQL cluster where it applies."""

from __future__ import annotations

import json
import os
import shutil
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from campaign.cli.app import main
from tests.ledger.conftest import SERIAL
from tests.ledger.postgres_cluster import PASSWORD

#: the session's four demo campaigns are made in the first test's setup (minutes on a
#: loaded machine): beyond the suite's 300 s default
pytestmark = pytest.mark.timeout(1200)

OLD_LEDGER = Path(__file__).parent / "data" / "ledger_rev0001.sqlite"
ROOT = Path(__file__).parents[2]


def run(capsys, *args) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(["history", *[str(a) for a in args]])
    out = capsys.readouterr()
    return status, out.out, out.err


def report_ids(capsys, url: str) -> list[str]:
    status, out, err = run(capsys, "list", "--db", url, "--json")
    assert status == 0, err
    return [c["report_id"] for c in json.loads(out)["campaigns"]]


def cli(*args) -> subprocess.Popen:
    env = {k: v for k, v in os.environ.items() if k != "STIFFNESS_CAMPAIGN_DB"}
    return subprocess.Popen([sys.executable, "-m", "campaign", "history",
                             *[str(a) for a in args]], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("same", [True, False], ids=["same-run", "two-runs"])
def test_two_processes_adding_at_once_land_exactly_once(ledger, demo_runs, capsys, same):
    """Two stations add at once to a ledger that does not exist yet (both migrate it):
    the same campaign lands once, two campaigns land once each."""
    runs = [demo_runs[0], demo_runs[0] if same else demo_runs[1]]
    procs = [cli("add", r, "--db", ledger, "--json") for r in runs]
    outs = [p.communicate(timeout=240) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1] for o in outs]
    added = [json.loads(o[0])["campaigns"][0]["added"] for o in outs]
    want = [json.loads((r / "analysis" / "results.json").read_text())["report_id"]
            for r in runs]
    assert sorted(report_ids(capsys, ledger)) == sorted(set(want))
    assert sorted(added) == ([False, True] if same else [True, True])


KILLED_ADD = """
import sys, time
from pathlib import Path
from campaign.jobs.history import AddOptions, add

def hold():
    print("FLUSHED", flush=True)
    time.sleep(600)
add(AddOptions((Path(sys.argv[1]),), sys.argv[2]), before_commit=hold)
"""


def test_kill_9_during_an_add_leaves_no_partial_record(ledger, demo_runs, capsys):
    assert run(capsys, "add", demo_runs[0], "--db", ledger)[0] == 0
    proc = subprocess.Popen([sys.executable, "-c", KILLED_ADD, str(demo_runs[1]), ledger],
                            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = proc.stdout.readline()
    assert line.strip() == "FLUSHED", proc.stderr.read()
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=60)
    first = json.loads((demo_runs[0] / "analysis" / "results.json").read_text())["report_id"]
    assert report_ids(capsys, ledger) == [first]
    # the ledger is whole: the killed campaign can be added again, once
    assert run(capsys, "add", demo_runs[1], "--db", ledger)[0] == 0
    assert len(report_ids(capsys, ledger)) == 2


def test_an_old_schema_ledger_is_migrated(demo_runs, capsys, tmp_path):
    db = tmp_path / "old.sqlite"
    shutil.copy(OLD_LEDGER, db)
    with sqlite3.connect(db) as conn:
        assert conn.execute("select version_num from alembic_version").fetchone() == ("0001",)
        old_row = conn.execute("select report_id, k_Nm_per_rad from campaigns").fetchall()
    status, out, err = run(capsys, "list", "--db", db, "--json")
    assert status == 0, err
    rows = json.loads(out)["campaigns"]
    assert [(r["report_id"], json.dumps(r["k_Nm_per_rad"])) for r in rows] == old_row
    with sqlite3.connect(db) as conn:
        assert conn.execute("select version_num from alembic_version").fetchone() == ("0002",)
        cols = [c[1] for c in conn.execute("pragma table_info(campaigns)")]
    assert cols[-2:] == ["temperatures", "software_version"]
    # the migrated ledger takes new campaigns of the same robot, and checks them
    assert run(capsys, "add", demo_runs[1], demo_runs[2], "--db", db)[0] == 0
    status, out, _ = run(capsys, "check", "--db", db, "--json", "--robot", SERIAL)
    assert status == 0 and json.loads(out)["robots"][0]["reference"] == rows[0]["report_id"]


def one_line_error(status: int, out: str, err: str) -> str:
    assert status == 2, (out, err)
    assert out == "" and len(err.strip().splitlines()) == 1 and "Traceback" not in err
    return err


def test_a_damaged_results_json_writes_nothing(demo_runs, capsys, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(demo_runs[0], copy)
    text = (copy / "analysis" / "results.json").read_text()
    (copy / "analysis" / "results.json").write_text(text[: len(text) // 2])
    db = tmp_path / "ledger.sqlite"
    err = one_line_error(*run(capsys, "add", demo_runs[1], copy, "--db", db))
    assert "results.json" in err and "not JSON" in err
    assert not db.exists()  # the good campaign before it was not recorded either


def test_another_robot_under_the_same_identity_is_refused(ledger, demo_runs, capsys, tmp_path):
    assert run(capsys, "add", demo_runs[0], "--db", ledger)[0] == 0
    other = tmp_path / "other"
    shutil.copytree(demo_runs[1], other)
    path = other / "analysis" / "results.json"
    doc = json.loads(path.read_text())
    doc["robot"], doc["report_id"] = "KUKA KR210 R2700", "RPT-0000000000000210"
    path.write_text(json.dumps(doc))
    err = one_line_error(*run(capsys, "add", other, "--db", ledger))
    assert "another robot under the same identity" in err
    assert len(report_ids(capsys, ledger)) == 1


def test_a_run_without_serial_asks_for_a_robot_id(demo_runs, capsys, tmp_path):
    copy = tmp_path / "run"
    shutil.copytree(demo_runs[0], copy)
    proto = copy / "protocol.toml"
    proto.write_text(proto.read_text().replace(f'serial = "{SERIAL}"\n', ""))
    db = tmp_path / "ledger.sqlite"
    err = one_line_error(*run(capsys, "add", copy, "--db", db))
    assert "--robot-id" in err and not db.exists()
    assert run(capsys, "add", copy, "--db", db, "--robot-id", "R-7")[0] == 0


def test_a_read_only_ledger_file_is_refused(demo_runs, capsys, tmp_path):
    db = tmp_path / "ledger.sqlite"
    assert run(capsys, "add", demo_runs[0], "--db", db)[0] == 0
    before = db.read_bytes()
    db.chmod(0o444)
    try:
        err = one_line_error(*run(capsys, "add", demo_runs[1], "--db", db))
        assert "read-only" in err
        assert db.read_bytes() == before
        assert run(capsys, "list", "--db", db)[0] == 0  # reading still works
    finally:
        db.chmod(0o644)
    # opened read-only (what a file without write permission is for a user who is not
    # root): reading works, adding is one line, nothing changes
    ro = f"sqlite:///file:{db}?mode=ro&uri=true"
    status, out, err = run(capsys, "trend", "--robot", SERIAL, "--db", ro, "--json")
    assert status == 0, err
    assert len(json.loads(out)["campaigns"]) == 1
    err = one_line_error(*run(capsys, "add", demo_runs[1], "--db", ro))
    assert "read-only" in err
    assert db.read_bytes() == before


def test_no_ledger_configured_is_one_line(capsys, monkeypatch):
    monkeypatch.delenv("STIFFNESS_CAMPAIGN_DB", raising=False)
    err = one_line_error(*run(capsys, "list"))
    assert "--db" in err and "STIFFNESS_CAMPAIGN_DB" in err


def test_the_environment_variable_names_the_ledger(demo_runs, capsys, monkeypatch, tmp_path):
    db = tmp_path / "env.sqlite"
    monkeypatch.setenv("STIFFNESS_CAMPAIGN_DB", str(db))
    assert run(capsys, "add", demo_runs[0])[0] == 0
    assert len(report_ids(capsys, f"sqlite:///{db}")) == 1


def test_a_wrong_password_and_an_unreachable_server_are_one_line(pg_cluster, demo_runs,
                                                                 capsys, tmp_path):
    if isinstance(pg_cluster, str):
        pytest.skip(f"PostgreSQL unavailable: {pg_cluster}")
    url = pg_cluster.create_database("ledger_password")
    wrong = url.replace(PASSWORD, "not-the-password-42")
    err = one_line_error(*run(capsys, "add", demo_runs[0], "--db", wrong))
    assert "password authentication failed" in err and "not-the-password-42" not in err
    from socket import socket

    with socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    down = f"postgresql://station:s3cret-pw@127.0.0.1:{port}/ledger"
    err = one_line_error(*run(capsys, "list", "--db", down))
    assert "Connection refused" in err or "connection failed" in err
    assert "s3cret-pw" not in err and "***" in err
    assert report_ids(capsys, url) == []  # nothing was written


def test_no_credentials_are_stored(pg_cluster, demo_runs, capsys):
    if isinstance(pg_cluster, str):
        pytest.skip(f"PostgreSQL unavailable: {pg_cluster}")
    url = pg_cluster.create_database("ledger_credentials")
    status, out, err = run(capsys, "add", demo_runs[0], "--db", url)
    assert status == 0 and PASSWORD not in out + err
    import psycopg

    with psycopg.connect(url) as conn:
        rows = conn.execute("select * from campaigns").fetchall()
    assert len(rows) == 1 and PASSWORD not in repr(rows)
