"""A complete run whose tests.csv lost the end of its last line (a crash while it was
written): analyze refuses it and says that ``campaign acquire --resume`` repairs it, and
the resume does (issue 29, item 7)."""

from __future__ import annotations

import pandas as pd

from campaign.acquire.progress import QuietReporter
from campaign.acquire.session import AcquireOptions, acquire
from campaign.cli import main


def test_analyze_names_the_resume_that_repairs_a_cut_line(small_plan, tmp_path, capsys):
    run = tmp_path / "run"
    outcome = acquire(small_plan, run, None, AcquireOptions(fake=True, assume_yes=True,
                                                            time_scale=100.0),
                      QuietReporter(), say=lambda s: None)
    assert outcome.status == "complete"
    whole = pd.read_csv(run / "tests.csv")
    text = (run / "tests.csv").read_text()
    last = text.rstrip("\n").rsplit("\n", 1)[1]
    (run / "tests.csv").write_text(text[:len(text) - 1 - len(last) // 2])  # cut mid-line
    capsys.readouterr()
    assert main(["analyze", str(run), "--no-report"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert f"line {len(whole) + 1}: last line is incomplete" in err[0]
    assert f"`campaign acquire --resume {run}`" in err[0], err
    # what the line says repairs it: the cut row is measured again, the others kept
    assert main(["acquire", "--resume", str(run), "--fake", "--yes", "--quiet",
                 "--time-scale", "100"]) == 0
    again = pd.read_csv(run / "tests.csv")
    assert list(again["test_id"]) == list(whole["test_id"])
    same = ["fx_N", "fy_N", "fz_N", "dx_mm", "dy_mm", "dz_mm"]
    assert again.iloc[:-1][same].equals(whole.iloc[:-1][same])  # rows before it unchanged
    capsys.readouterr()
    assert main(["analyze", str(run), "--no-report", "--out", str(tmp_path / "a")]) == 0
