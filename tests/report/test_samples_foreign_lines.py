"""Lines of samples.jsonl that are JSON objects but not readings (another run's progress
records appended to a finished run, issue 29 item 2) are noticed by analyze: a WARNING
naming the lines, left out of samples.parquet; tests.csv and the result are untouched."""

from __future__ import annotations

import json

import pandas as pd
from report_runs import write_run

from campaign.cli import main
from tests.report.test_analyze_damaged_run import _samples


def test_foreign_json_lines_are_warned_and_left_out(tmp_path, rows, capsys):
    clean = write_run(tmp_path / "clean", rows)
    (clean / "samples.jsonl").write_text("\n".join(_samples(4)) + "\n")
    run = write_run(tmp_path / "run", rows)
    progress = [json.dumps({"event": "phase", "phase": "approach", "test_id": 1, "done": 0,
                            "total": 3}),
                json.dumps({"event": "message", "text": "settling"}),
                json.dumps({"event": "finish", "status": "complete"})]
    lines = _samples(4)
    (run / "samples.jsonl").write_text("\n".join(lines[:2] + progress + lines[2:]) + "\n")
    results = {}
    for name, d in (("clean", clean), ("run", run)):
        capsys.readouterr()
        assert main(["analyze", str(d), "--no-report", "--json"]) == 0
        cap = capsys.readouterr()
        results[name] = json.loads(cap.out)
    warned = [w for w in results["run"]["warnings"] if "samples.jsonl" in w]
    assert warned == ["samples.jsonl: 3 line(s) that are not readings (JSON objects without "
                      "instrument, quantity, value: line 3, 4, 5), skipped: something else "
                      "wrote into the run's raw readings (the analysis uses tests.csv, which "
                      "is not affected)"]
    assert not any("samples.jsonl" in w for w in results["clean"]["warnings"])
    assert pd.read_parquet(run / "samples.parquet")["test_id"].tolist() == [1, 2, 3, 4]
    assert results["run"]["joint_stiffness_Nm_per_rad"] == \
        results["clean"]["joint_stiffness_Nm_per_rad"]
