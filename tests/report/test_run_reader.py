"""campaign.run_format.reader: complete, aborted and malformed run directories."""

from __future__ import annotations

import json

import numpy as np
import pytest
from report_runs import HEADER, REPEATS, write_run

from analysis.errors import InputError
from campaign.run_format.reader import read_run


def test_complete_run_counts_flags_and_si_table(complete_run):
    run = read_run(complete_run, export=False)
    assert run.status == "complete" and not run.partial
    assert len(run.tests) == 15 and run.n_failed == 1 and len(run.ok) == 14
    assert run.n_planned == 5 * REPEATS
    assert run.flag_counts() == {"drift": 1, "saturation": 1, "retried": 1}
    flagged = run.flagged()
    assert flagged["line"].tolist() == [6, 12]  # header is line 1
    assert flagged["status"].tolist() == ["ok", "failed"]
    # SI table: mm -> m, deg -> rad; the failed row (file line 12) is left out
    assert 12 not in run.ok["line"].tolist()
    raw = run.tests[run.tests["line"] == 2].iloc[0]
    si = run.ok[run.ok["line"] == 2].iloc[0]
    assert si["dx_m"] == pytest.approx(float(raw["dx_mm"]) * 1e-3, rel=1e-12)
    assert si["q2_rad"] == pytest.approx(np.radians(40.0), rel=1e-12)
    assert run.notes == []


def test_protocol_changed_after_the_run_is_refused(tmp_path, rows):
    run_dir = write_run(tmp_path / "r", rows)
    (run_dir / "protocol.toml").write_text((run_dir / "protocol.toml").read_text() + "\n# x\n")
    with pytest.raises(InputError, match="protocol.toml does not match protocol_sha256"):
        read_run(run_dir, export=False)


def test_plan_changed_after_the_run_is_said_loudly(tmp_path, rows):
    import hashlib

    run_dir = write_run(tmp_path / "r", rows)
    (run_dir / "plan.csv").write_text("test\n1\n")
    meta = json.loads((run_dir / "metadata.json").read_text())
    meta["plan_sha256"] = hashlib.sha256(b"test\n1\n").hexdigest()
    (run_dir / "metadata.json").write_text(json.dumps(meta))
    assert read_run(run_dir, export=False).notes == []  # unchanged copy: nothing said
    (run_dir / "plan.csv").write_text("test\n2\n")
    notes = read_run(run_dir, export=False).notes
    assert len(notes) == 1 and notes[0].startswith("WARNING: plan.csv does not match")


def test_aborted_run_drops_half_written_line(aborted_run):
    run = read_run(aborted_run, export=False)
    assert run.partial and run.status == "aborted"
    assert len(run.tests) == 12 and len(run.ok) == 12
    assert any("being written" in n for n in run.notes)


def test_parquet_exports_written_when_missing(tmp_path, rows):
    run_dir = write_run(tmp_path / "r", rows)
    read_run(run_dir)
    import pandas as pd

    back = pd.read_parquet(run_dir / "tests.parquet")
    assert len(back) == 15 and "flags" in back.columns


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda d: (d / "metadata.json").unlink(), "no metadata.json"),
        (lambda d: (d / "tests.csv").unlink(), "finished no test"),
        (lambda d: (d / "metadata.json").write_text("{not json"), "not valid JSON"),
        (lambda d: (d / "metadata.json").write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00"),
         "metadata.json is not UTF-8 text"),
        (lambda d: (d / "metadata.json").write_text("[1, 2]"),
         "expected a JSON object, found a list"),
        (lambda d: _cell(d, 4, "test_id", "x"), "line 4, column test_id: 'x' is not a whole"),
        (lambda d: _duplicate(d, 3), "lines 3 and 17: test 1 repeat 2 recorded twice"),
        (lambda d: _insert(d, 5, "garbage,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,\n"),
         "not a CSV table"),
        (lambda d: _meta(d, status="paused"), "status 'paused'"),
        (lambda d: _meta(d, format_version=7), "format_version 7"),
        (lambda d: _cell(d, 3, "dy_mm", "abc"), "line 3, column dy_mm: 'abc' is not a number"),
        (lambda d: _cell(d, 4, "status", "maybe"), "line 4, column status: 'maybe'"),
        (lambda d: _cell(d, 5, "q2_deg", ""), "line 5, column q2_deg: empty"),
    ],
)
def test_bad_runs_name_the_file_and_place(tmp_path, rows, edit, message):
    run_dir = write_run(tmp_path / "r", rows)
    edit(run_dir)
    with pytest.raises(InputError) as err:
        read_run(run_dir, export=False)
    assert message in str(err.value)
    assert str(run_dir) in str(err.value)


def test_a_run_with_only_failed_tests_is_refused(tmp_path, rows):
    failed = [dict(r, status="failed") for r in rows]
    with pytest.raises(InputError, match="no test finished with status ok"):
        read_run(write_run(tmp_path / "r", failed), export=False)


def test_truncated_line_in_a_complete_run_is_an_error(tmp_path, rows):
    run_dir = write_run(tmp_path / "r", rows, truncate_last=True)
    with pytest.raises(InputError, match="line 16: last line is incomplete"):
        read_run(run_dir, export=False)


def _meta(run_dir, **changes):
    meta = json.loads((run_dir / "metadata.json").read_text())
    meta.update(changes)
    (run_dir / "metadata.json").write_text(json.dumps(meta))


def _cell(run_dir, line, column, value):
    lines = (run_dir / "tests.csv").read_text().splitlines()
    cells = lines[line - 1].split(",")
    cells[HEADER.index(column)] = value
    lines[line - 1] = ",".join(cells)
    (run_dir / "tests.csv").write_text("\n".join(lines) + "\n")


def _duplicate(d, line):
    """Append a copy of file line ``line`` of tests.csv."""
    lines = (d / "tests.csv").read_text().splitlines(keepends=True)
    (d / "tests.csv").write_text("".join(lines) + lines[line - 1])


def _insert(d, line, text):
    """Insert ``text`` as file line ``line`` of tests.csv."""
    lines = (d / "tests.csv").read_text().splitlines(keepends=True)
    (d / "tests.csv").write_text("".join(lines[:line - 1]) + text + "".join(lines[line - 1:]))
