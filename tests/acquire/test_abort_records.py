"""What the record says after an abort: robot and load, sessions, write failures."""

from __future__ import annotations

import errno
import json
import os

import pandas as pd
import pytest
from test_faults import Injector, _run

from campaign.acquire.progress import QuietReporter
from campaign.acquire.rundir import WriteFailure, atomic_write, finished_tests
from campaign.acquire.runner import load_may_hang
from drivers.errors import DeviceFault


def _events(run) -> list[dict]:
    return [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]


def _load_history(events: list[dict]) -> list[str]:
    return [e["event"] for e in events if e["event"] in ("load_applied", "load_removed",
                                                          "load_left")]


class Recorder(Injector):
    """Injector that also keeps the messages shown to the operator."""

    def __init__(self, actions) -> None:
        super().__init__(actions)
        self.messages: list[str] = []
        self.lab_load = None

    def message(self, text: str) -> None:
        self.messages.append(text)

    def finish(self, *args) -> None:
        if self.client is not None:
            self.lab_load = self.client.call("state")["load"]
        super().finish(*args)


def test_fault_while_loaded_records_every_removal_then_resume_marks_sessions(small_plan,
                                                                            tmp_path):
    out = tmp_path / "run"
    # the tracker loses its beam while the load hangs on the tool, at both attempts
    lost = lambda c: c.call("fault", device="emscon", fault="beam_lost",  # noqa: E731
                            count=1)
    rep = Recorder([("load_applied", 2, None, lost)])
    outcome = _run(small_plan, out, rep)
    assert outcome.status == "failed" and "device fault after a retry" in outcome.reason
    assert rep.lab_load == [0, 0, 0, 0, 0, 0]  # the load is off the tool ...
    events = _events(out)
    # ... and the record says so: every application is followed by its removal
    assert _load_history(events) == ["load_applied", "load_removed"] * 3
    removed = [e for e in events if e["event"] == "load_removed"]
    assert [e["reason"] for e in removed[1:]] == ["before the retry", "safe stop"]
    kinds = [e["event"] for e in events]
    assert kinds.index("robot_stopped") > kinds.index("abort")
    assert not load_may_hang(out)
    assert {e.get("session") for e in events} == {1}

    outcome = _run(small_plan, out, QuietReporter(), resume=out)
    assert outcome.status == "complete", outcome.reason
    assert finished_tests(out) == {(1, 1), (2, 1), (3, 1)}
    meta = json.loads((out / "metadata.json").read_text())
    assert [s["id"] for s in meta["sessions"]] == [1, 2]
    samples = pd.read_json(out / "samples.jsonl", lines=True)
    sets = samples[samples.test_id == 2].groupby(["session", "attempt"]).size()
    # the interrupted test: two attempts in session 1, the one kept in session 2
    assert list(sets.index) == [(1, 1), (1, 2), (2, 1)]
    assert (sets > 0).all()
    assert set(samples[samples.test_id == 1].session) == {1}
    assert set(samples[samples.test_id == 3].session) == {2}
    row = pd.read_csv(out / "tests.csv").set_index("test_id").loc[2]
    kept = samples[(samples.test_id == 2) & (samples.session == 2)]
    # stamped when the last reading of the kept set was taken (the simulated lab's clock:
    # a tracker reading takes no simulated time, so not later)
    assert row.status == "ok" and pd.Timestamp(row.t_utc) == pd.Timestamp(kept.t_utc.max())


def test_load_that_cannot_be_removed_is_said_everywhere(small_plan, tmp_path, monkeypatch):
    from campaign.run_format.reader import read_run
    from drivers.manual import ManualLoad

    out = tmp_path / "run"
    stuck = {"on": False}
    real_remove = ManualLoad.remove

    def remove(self):
        if stuck["on"]:
            raise DeviceFault("the operator does not answer")
        return real_remove(self)

    monkeypatch.setattr(ManualLoad, "remove", remove)

    def overload(c):
        stuck["on"] = True
        c.call("apply_load", wrench=[0, 3000, 3000, 0, 0, 0], name="too much")

    rep = Recorder([("load_applied", 2, None, overload)])
    outcome = _run(small_plan, out, rep)
    assert outcome.status == "aborted" and "safety stop" in outcome.reason
    assert "LOAD STILL APPLIED: could not remove the load" in outcome.reason
    assert any(m.startswith("THE LOAD IS STILL APPLIED") for m in rep.messages)
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["reason"] == outcome.reason
    assert "the operator does not answer" in meta["load_left_applied"]
    events = _events(out)
    assert _load_history(events) == ["load_applied", "load_removed", "load_applied",
                                     "load_left"]
    assert load_may_hang(out)  # a resume takes it off before any motion
    notes = read_run(out, export=False).notes
    assert any(n.startswith("WARNING: the load was left applied at the end of session 1 "
                            "(test 2, repeat 1)") for n in notes)


def test_disk_full_mid_run_stops_safely_and_the_run_resumes(small_plan, tmp_path,
                                                            monkeypatch):
    out = tmp_path / "run"
    real_write = os.write
    state = {"samples": 0}

    def write(fd, data):
        try:
            name = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            name = ""
        if name.endswith("samples.jsonl"):
            state["samples"] += 1
            if state["samples"] == 60:  # inside test 2 (about 43 samples a test)
                real_write(fd, bytes(data)[:7])  # part of the line reaches the disk
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real_write(fd, data)

    monkeypatch.setattr(os, "write", write)
    rep = Recorder([])
    outcome = _run(small_plan, out, rep)
    monkeypatch.setattr(os, "write", real_write)
    assert outcome.status == "failed"
    assert outcome.reason.startswith(f"cannot write samples.jsonl in {out}: No space left on "
                                     "device; free space or fix the permissions, then "
                                     "resume the run")
    # the reason is the run's, read by the command line and the page alike: no option in it
    assert "--" not in outcome.reason
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["status"] == "failed" and meta["reason"] == outcome.reason
    assert not [p.name for p in out.iterdir() if p.name.endswith(".tmp")]
    text = (out / "samples.jsonl").read_text()
    assert text.endswith("\n") and len(text.splitlines()) == 59  # the partial line cut off
    for line in text.splitlines():
        json.loads(line)
    events = _events(out)
    kinds = [e["event"] for e in events]
    assert "abort" in kinds and "robot_stopped" in kinds
    assert rep.lab_load == [0, 0, 0, 0, 0, 0] and not load_may_hang(out)
    assert finished_tests(out) == {(1, 1)}

    outcome = _run(small_plan, out, QuietReporter(), resume=out)  # space is back
    assert outcome.status == "complete", outcome.reason
    tests = pd.read_csv(out / "tests.csv")
    assert sorted(zip(tests.test_id, tests.repeat, strict=True)) == [(1, 1), (2, 1), (3, 1)]


def test_failed_metadata_write_keeps_the_old_file_and_no_temp(tmp_path, monkeypatch):
    target = tmp_path / "metadata.json"
    target.write_text('{"status": "running"}\n')

    def replace(src, dst):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(WriteFailure, match="cannot write metadata.json .*No space left"):
        atomic_write(target, '{"status": "failed"}\n')
    assert target.read_text() == '{"status": "running"}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["metadata.json"]
