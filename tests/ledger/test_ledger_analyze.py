"""``campaign analyze`` with a ledger: it records the campaign and its report gets a history
section (this campaign against the robot's earlier ones); without one, nothing is recorded."""

from __future__ import annotations

import html
import json
import re
import shutil

import pytest

from campaign.cli.app import main
from tests.ledger.conftest import SERIAL

#: the session's four demo campaigns are made in the first test's setup (minutes on a
#: loaded machine): beyond the suite's 300 s default
pytestmark = pytest.mark.timeout(1200)


def test_analyze_records_and_reports_the_history(demo_runs, capsys, tmp_path, monkeypatch):
    monkeypatch.delenv("STIFFNESS_CAMPAIGN_DB", raising=False)
    db = tmp_path / "ledger.sqlite"
    assert main(["history", "add", *map(str, demo_runs[:3]), "--db", str(db)]) == 0
    run = tmp_path / "run"
    shutil.copytree(demo_runs[3], run, ignore=shutil.ignore_patterns("analysis"))
    capsys.readouterr()
    assert main(["analyze", str(run), "--db", str(db), "--trials", "10", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ledger"] == {"report_id": doc["report_id"], "robot": SERIAL,
                             "date": doc["ledger"]["date"], "added": True}
    text = re.sub(r"\s+", " ", html.unescape(re.sub(
        "<[^>]+>", " ", (run / "analysis" / "report.html").read_text())))
    section = text[text.index("Campaigns of robot"):text.index("Residuals and validation",
                                                               text.index("Campaigns of robot"))]
    assert f"{doc['report_id']} (this)" in section
    verdicts = re.findall(r" (\d) ([+-]\d+\.\d\d) \[[^\]]+\] (DROPPED|no drop shown)", section)
    assert [(j, v) for j, _, v in verdicts] == [("1", "no drop shown"), ("2", "DROPPED"),
                                                ("3", "no drop shown"), ("4", "no drop shown"),
                                                ("5", "no drop shown"), ("6", "no drop shown")]
    first = json.loads((demo_runs[0] / "analysis" / "results.json").read_text())
    k_ref = first["joint_stiffness_Nm_per_rad"][1]
    assert float(verdicts[1][1]) == round(100 * (doc["joint_stiffness_Nm_per_rad"][1] / k_ref
                                                 - 1), 2)
    assert main(["history", "check", "--db", str(db)]) == 3


def test_analyze_without_a_ledger_records_nothing(demo_runs, capsys, tmp_path, monkeypatch):
    monkeypatch.delenv("STIFFNESS_CAMPAIGN_DB", raising=False)
    run = tmp_path / "run"
    shutil.copytree(demo_runs[0], run, ignore=shutil.ignore_patterns("analysis"))
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["analyze", str(run), "--no-report", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert "ledger" not in doc
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert "History of this robot" not in (run / "analysis" / "results.json").read_text()
