"""kill -9 of the acquire process at seeded moments, then --resume: nothing lost, nothing twice."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from campaign.acquire.rundir import RunDir, finished_tests, repair_tail

ROOT = Path(__file__).resolve().parents[2]


def _lines(path: Path) -> int:
    try:
        with open(path, "rb") as fh:
            return fh.read().count(b"\n")
    except FileNotFoundError:
        return 0


def _start(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "campaign", "acquire", *args, "--fake",
                             "--yes", "--quiet", "--time-scale", "100"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _kill_when(proc: subprocess.Popen, samples: Path, n: int, timeout: float = 90) -> bool:
    """kill -9 ``proc`` once samples.jsonl has ``n`` lines; False if it ended first."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return False
        if _lines(samples) >= n:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
            return True
        time.sleep(0.002)
    proc.kill()
    raise AssertionError("acquire did not progress")


def test_kill9_at_seeded_moments_then_resume(kr240_plan, make_variant, tmp_path):
    plan = make_variant(kr240_plan, tmp_path / "plan", repeats=2)  # 5 tests x 2 repeats
    run = tmp_path / "run"
    samples = run / "samples.jsonl"
    rng = np.random.default_rng(int(os.environ.get("ACQUIRE_KILL_SEED", "20261122")))
    # a measurement writes about 43 samples (430 in all); kill points spread over the whole run
    kill_at = np.sort(rng.integers(1, 400, size=3))
    proc = _start(["--plan", str(plan), "--out", str(run)])
    kills = 0
    for n in kill_at:
        if _kill_when(proc, samples, int(n)):
            kills += 1
            meta = json.loads((run / "metadata.json").read_text())
            assert meta["status"] == "running"  # readable after the kill
            before = finished_tests(run)
        proc = _start(["--resume", str(run)])
    proc.wait(timeout=120)
    assert proc.returncode == 0, proc.stderr.read()
    assert kills >= 2, f"only {kills} kills landed at {kill_at}"
    assert before  # at least one kill landed after a finished test

    tests = pd.read_csv(run / "tests.csv")
    keys = list(zip(tests.test_id, tests.repeat, strict=True))
    assert len(keys) == len(set(keys)), "duplicated test rows"
    assert sorted(keys) == [(t, r) for t in range(1, 6) for r in (1, 2)], "missing tests"
    assert (tests.status == "ok").all()
    meta = json.loads((run / "metadata.json").read_text())
    assert meta["status"] == "complete"
    assert len(meta["sessions"]) == kills + 1
    events = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    assert sum(e["event"] == "session_start" for e in events) == kills + 1
    # every line of the appended files is whole
    for name in ("samples.jsonl", "events.jsonl"):
        for line in (run / name).read_text().splitlines():
            json.loads(line)


def test_resume_cuts_a_partial_last_line(tmp_path):
    f = tmp_path / "samples.jsonl"
    f.write_bytes(b'{"a": 1}\n{"b": 2}\n{"c": ')
    assert repair_tail(f) == len(b'{"c": ')
    assert f.read_bytes() == b'{"a": 1}\n{"b": 2}\n'
    assert repair_tail(f) == 0


def test_resume_of_a_complete_run_measures_nothing(kr240_plan, make_variant, tmp_path, cli):
    plan = make_variant(kr240_plan, tmp_path / "plan", tests=1, repeats=1)
    run = tmp_path / "run"
    first = cli("acquire", "--plan", str(plan), "--out", str(run), "--fake", "--yes", "--json",
                "--time-scale", "100")
    assert first.returncode == 0, first.stderr
    lines = [json.loads(line) for line in first.stdout.splitlines()]  # JSON lines mode
    assert lines[-1]["event"] == "finish" and lines[-1]["status"] == "complete"
    assert lines[-1]["ok"] == 1
    assert any(e["event"] == "phase" and e.get("phase") == "settle_loaded" for e in lines)
    assert any("deflection_mm" in e for e in lines)
    size = (run / "samples.jsonl").stat().st_size
    again = cli("acquire", "--resume", str(run), "--fake", "--yes", "--quiet")
    assert again.returncode == 0, again.stderr
    assert (run / "samples.jsonl").stat().st_size == size
    assert len(pd.read_csv(run / "tests.csv")) == 1
    # resuming without --fake a run made with --fake is refused
    wrong = cli("acquire", "--resume", str(run), "--yes")
    assert wrong.returncode == 2 and "--fake" in wrong.stderr
    RunDir.open(run).close()


def test_ctrl_c_stops_unloads_records_and_resumes(kr240_plan, make_variant, tmp_path):
    plan = make_variant(kr240_plan, tmp_path / "plan", tests=3, repeats=1)
    run = tmp_path / "run"
    proc = _start(["--plan", str(plan), "--out", str(run)])
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:  # interrupt while the load hangs on the tool
        events = (run / "events.jsonl").read_text() if (run / "events.jsonl").exists() else ""
        if events.count('"load_applied"') > events.count('"load_removed"') and \
                '"test_done"' in events:
            break
        time.sleep(0.002)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=30)
    assert proc.returncode == 1, err
    meta = json.loads((run / "metadata.json").read_text())
    assert meta["status"] == "aborted" and "Ctrl-C" in meta["reason"]
    events = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    kinds = [e["event"] for e in events]
    stop = kinds.index("interrupt")
    assert "load_removed" in kinds[stop:]  # automated (simulated operator): load taken off
    done = finished_tests(run)
    # the last lines: the whole run's count, what the records say of the robot and the
    # load, and the command that resumes
    last = err.strip().splitlines()[-3:]
    assert last[0].startswith(f"run aborted: interrupted by the operator (Ctrl-C) "
                              f"({len(done)}/3 measurements: {len(done)} ok, 0 failed)")
    assert last[1] == "after the stop: robot stopped; load removed"
    assert last[2] == f"to continue: campaign acquire --resume {run} --fake"
    proc = _start(["--resume", str(run)])
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 0, err
    tests = pd.read_csv(run / "tests.csv")
    keys = list(zip(tests.test_id, tests.repeat, strict=True))
    assert sorted(keys) == [(1, 1), (2, 1), (3, 1)] and done <= set(keys)
    # after the resume the count is the whole run's, not this session's
    assert err.strip().splitlines()[-1].startswith(
        "run complete (3/3 measurements: 3 ok, 0 failed)"), err


def test_a_run_is_written_by_one_process_at_a_time(tmp_path):
    from analysis.errors import InputError

    run = RunDir.create(tmp_path / "run", {"fake": True}, "protocol.toml", "x = 1\n",
                        "test\n")
    try:
        with pytest.raises(InputError, match="another campaign acquire"):
            RunDir.open(tmp_path / "run")
    finally:
        run.close()
    RunDir.open(tmp_path / "run").close()  # free again once closed
