"""The fleet ledger's commands on four demo campaigns of one robot (simulated lab).

The fourth campaign's lab has k2 10 % lower: ``history check`` must pass after three
campaigns (exit 0) and raise an alarm on joint 2 only after four (exit 3), with an
interval of the change that holds the true -10 %. Every test runs on SQLite and on
a throwaway PostgreSQL cluster; the trend is the same from both.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from campaign.cli.app import main
from tests.ledger.conftest import K2_WORN, SERIAL, new_ledger

#: the session's four demo campaigns are made in the first test's setup (minutes on a
#: loaded machine): beyond the suite's 300 s default
pytestmark = pytest.mark.timeout(1200)


def run(capsys, *args) -> tuple[int, str, str]:
    capsys.readouterr()
    status = main(["history", *[str(a) for a in args]])
    out = capsys.readouterr()
    return status, out.out, out.err


def results(run_dir: Path) -> dict:
    return json.loads((run_dir / "analysis" / "results.json").read_text())


def test_three_campaigns_pass_and_a_worn_joint_2_alarms_alone(ledger, demo_runs, capsys):
    status, out, err = run(capsys, "add", *demo_runs[:3], "--db", ledger)
    assert status == 0, err
    assert out.count("recorded:") == 3
    status, out, _ = run(capsys, "check", "--db", ledger, "--json")
    assert status == 0
    doc = json.loads(out)
    assert doc["alarms"] == []
    assert doc["robots"][0]["status"] == "ok" and len(doc["robots"][0]["tests"]) == 6
    assert run(capsys, "add", demo_runs[3], "--db", ledger)[0] == 0
    status, out, _ = run(capsys, "check", "--db", ledger, "--json", "--robot", SERIAL)
    assert status == 3
    doc = json.loads(out)
    assert [a["joint"] for a in doc["alarms"]] == [2]
    alarm = doc["alarms"][0]
    assert alarm["robot"] == SERIAL and alarm["test"].startswith("one-sided bound")
    first, fourth = results(demo_runs[0]), results(demo_runs[3])
    assert alarm["campaigns"] == [first["report_id"], fourth["report_id"]]
    k_a, k_b = first["joint_stiffness_Nm_per_rad"][1], fourth["joint_stiffness_Nm_per_rad"][1]
    assert alarm["change_percent"] == pytest.approx(100 * (k_b / k_a - 1), rel=1e-12)
    lo, hi = alarm["interval"]
    # the true change of the lab's k2 lies inside the interval, and the bound is below -5 %
    assert lo < 100 * (K2_WORN - 1) < hi < -5.0
    # the text face says the same, one alarm line
    status, out, _ = run(capsys, "check", "--db", ledger)
    assert status == 3 and [s for s in out.splitlines() if s.startswith("ALARM")] == [
        f"ALARM robot {SERIAL} joint 2: {alarm['change_percent']:+.2f} %, interval "
        f"[{lo:.2f}, {hi:.2f}] % (one-sided bound, Holm over joints)"]
    # with a 15 % minimum change the same data raise no alarm
    assert run(capsys, "check", "--db", ledger, "--min-change", "15")[0] == 0


def test_adding_twice_records_once(ledger, demo_runs, capsys):
    assert run(capsys, "add", demo_runs[0], "--db", ledger)[0] == 0
    status, out, _ = run(capsys, "add", demo_runs[0] / "analysis", "--db", ledger, "--json")
    assert status == 0
    assert json.loads(out)["campaigns"][0]["added"] is False
    status, out, _ = run(capsys, "list", "--db", ledger, "--json")
    assert [c["report_id"] for c in json.loads(out)["campaigns"]] == [
        results(demo_runs[0])["report_id"]]


def test_trend_is_the_recorded_numbers_oldest_first(ledger, demo_runs, capsys, tmp_path):
    # added newest first: the trend still lists them by campaign date
    assert run(capsys, "add", *reversed(demo_runs), "--db", ledger)[0] == 0
    status, out, _ = run(capsys, "trend", "--robot", SERIAL, "--db", ledger, "--json",
                         "--plot", tmp_path / "trend.png")
    assert status == 0
    doc = json.loads(out)
    assert doc["robot"] == SERIAL
    assert [c["report_id"] for c in doc["campaigns"]] == [results(r)["report_id"]
                                                         for r in demo_runs]
    assert [c["date"] for c in doc["campaigns"]] == sorted(c["date"] for c in doc["campaigns"])
    for c, r in zip(doc["campaigns"], demo_runs, strict=True):
        res = results(r)
        assert c["k_Nm_per_rad"] == res["joint_stiffness_Nm_per_rad"]
        assert c["ci95_Nm_per_rad"] == res["ci95_Nm_per_rad"]
        assert all(lo < k < hi for k, (lo, hi) in zip(c["k_Nm_per_rad"],
                                                      c["ci95_Nm_per_rad"], strict=True))
    assert (tmp_path / "trend.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_trend_is_identical_from_sqlite_and_postgresql(pg_cluster, demo_runs, capsys,
                                                       tmp_path):
    docs = []
    for backend in ("sqlite", "postgresql"):
        url = new_ledger(backend, pg_cluster, tmp_path)
        assert run(capsys, "add", *demo_runs, "--db", url)[0] == 0
        status, out, _ = run(capsys, "trend", "--robot", SERIAL, "--db", url, "--json")
        assert status == 0
        docs.append(out)
    assert docs[0] == docs[1]
    assert len(json.loads(docs[0])["campaigns"]) == 4


def test_verify_reports_a_changed_file(ledger, demo_runs, capsys, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(demo_runs[1], copy)
    assert run(capsys, "add", copy, "--db", ledger)[0] == 0
    assert run(capsys, "verify", "--db", ledger)[0] == 0
    with open(copy / "tests.csv", "a") as f:
        f.write("\n")
    (copy / "protocol.toml").unlink()
    status, out, _ = run(capsys, "verify", "--db", ledger, "--json")
    assert status == 3
    doc = json.loads(out)
    assert [m["file"] for m in doc["mismatches"]] == ["tests.csv"]
    assert [m["file"] for m in doc["missing"]] == ["protocol"]
    assert doc["checked"] == 3


def test_a_correction_supersedes_the_old_record_which_is_left_out(ledger, demo_runs, capsys):
    """A correction is a new record: the superseded one stays, marked, out of the test."""
    first, second = demo_runs[0], demo_runs[1]
    assert run(capsys, "add", first, second, "--db", ledger)[0] == 0
    old = results(second)["report_id"]
    status, _, err = run(capsys, "add", demo_runs[2], "--db", ledger, "--supersedes", old)
    assert status == 0, err
    status, out, _ = run(capsys, "trend", "--robot", SERIAL, "--db", ledger, "--json")
    rows = {c["report_id"]: c for c in json.loads(out)["campaigns"]}
    assert len(rows) == 3
    assert rows[old]["compared"] is False
    assert rows[old]["reason"] == f"superseded by {results(demo_runs[2])['report_id']}"
