"""campaign analyze of a damaged run: what it falls back to or skips is said, and kept."""

from __future__ import annotations

import json

import pandas as pd
from report_runs import write_run

from campaign.cli import main


def _samples(n: int) -> list[str]:
    return [json.dumps({"t_utc": f"2026-11-20T10:00:{i:02d}Z", "session": 1, "test_id": i + 1,
                        "repeat": 1, "phase": "loaded", "instrument": "tracker",
                        "quantity": "tool_pose", "unit": "mm", "frame": "base",
                        "value": [float(i), 0.0, 0.0], "sigma": None}) for i in range(n)]


def test_a_deleted_protocol_copy_is_warned_and_recorded(tmp_path, rows, capsys):
    run = write_run(tmp_path / "run", rows)
    (run / "protocol.toml").unlink()
    capsys.readouterr()
    assert main(["analyze", str(run), "--no-report"]) == 0
    err = capsys.readouterr().err
    line = [ln for ln in err.splitlines() if ln.startswith("WARNING: no protocol copy")]
    assert len(line) == 1 and "it was deleted" in line[0]
    assert "noise from defaults" in line[0] and "'kr240-2'" in line[0]
    res = json.loads((run / "analysis" / "results.json").read_text())
    assert res["warnings"][0] == line[0].removeprefix("WARNING: ")
    # said once on the terminal, not again with the result's warnings
    assert err.count("no protocol copy") == 1


def test_a_damaged_samples_line_is_warned_recorded_and_left_out(tmp_path, rows, capsys):
    run = write_run(tmp_path / "run", rows)
    lines = _samples(6)
    lines[2] = lines[2][:40]  # cut short (a crash mid-write)
    lines[4] = "\xe9t\xe9"  # not JSON
    (run / "samples.jsonl").write_text("\n".join(lines) + "\n\n", encoding="latin-1")
    capsys.readouterr()
    assert main(["analyze", str(run), "--no-report", "--json"]) == 0
    cap = capsys.readouterr()
    assert "Traceback" not in cap.err
    warned = [ln for ln in cap.err.splitlines() if "samples.jsonl" in ln]
    assert len(warned) == 1 and "2 damaged line(s)" in warned[0] and "line 3, 5" in warned[0]
    out = json.loads(cap.out)
    assert any(w.startswith("samples.jsonl: 2 damaged line(s)") for w in out["warnings"])
    res = json.loads((run / "analysis" / "results.json").read_text())
    assert res["warnings"] == out["warnings"]
    table = pd.read_parquet(run / "samples.parquet")
    assert table["test_id"].tolist() == [1, 2, 4, 6]


def test_an_intact_run_has_no_such_warning(complete_run, tmp_path, capsys):
    capsys.readouterr()
    assert main(["analyze", str(complete_run), "--no-report", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert "WARNING" not in err
    res = json.loads((tmp_path / "o" / "results.json").read_text())
    assert not any("protocol copy" in w or "samples.jsonl" in w for w in res["warnings"])


def test_the_unfinished_last_samples_line_of_a_stopped_run_is_a_note(tmp_path, rows, capsys):
    """kill -9 mid-write leaves a partial last line: dropped with a note, as in tests.csv;
    in a complete run the same line is damage (a WARNING)."""
    for status, loud in (("aborted", False), ("complete", True)):
        run = write_run(tmp_path / status, rows, status=status)
        (run / "samples.jsonl").write_text("\n".join(_samples(3)) + '\n{"t_utc": "2026-')
        capsys.readouterr()
        assert main(["analyze", str(run), "--no-report"]) == 0
        err = capsys.readouterr().err
        res = json.loads((run / "analysis" / "results.json").read_text())
        assert ("WARNING: samples.jsonl: 1 damaged line(s) (not a JSON object: line 4)"
                in err) is loud
        assert any("samples.jsonl" in w for w in res["warnings"]) is loud
        assert len(pd.read_parquet(run / "samples.parquet")) == 3
