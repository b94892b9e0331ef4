"""The live panel of ``campaign acquire`` at 80 columns, and the closing lines.

What it shows (this test's readings only, angles labelled with their convention), that a
Ctrl-C never cuts a frame in two, and that the closing lines come from the run directory
(whole-run counts, the robot and the load after the stop, the resume command).
"""

from __future__ import annotations

import io
import json
import os
import re
import signal

import numpy as np
import pytest
from rich.console import Console

from campaign.acquire.ending import ending, final_lines, safe_state
from campaign.acquire.progress import RichReporter, interrupt_after


def _reporter() -> tuple[RichReporter, io.StringIO]:
    out = io.StringIO()
    console = Console(file=out, width=80, force_terminal=True, color_system=None)
    return RichReporter(console=console), out


def _panel_text(rep: RichReporter) -> str:
    console = Console(width=80, record=True, file=io.StringIO(), color_system=None)
    console.print(rep._render())
    return console.export_text()


def test_panel_blanks_the_previous_tests_readings_and_labels_the_convention():
    rep, _ = _reporter()
    rep.phase(run_dir="runs/[x]", test_id=1, repeat=1, attempt=1, pose="P1", done=0, total=3,
              q_ctrl_deg=np.array([0, -53.42, 89.94, -45, -45, -45.0]),
              wrench=np.array([0, 2200, 2200, 200, 200, 0.0]),
              deflection_mm=np.array([1.234, -0.0001, 0.5]))
    text = _panel_text(rep)
    assert "runs/[x]" in text  # a path is never read as markup
    assert "[0.00 -53.42 89.94 -45.00 -45.00 -45.00] controller convention" in text
    assert "[0.0 2200.0 2200.0 200.0 200.0 0.0] N, N m" in text
    assert "[1.234 0.000 0.500] mm" in text  # a rounded zero has no sign
    # the next test starts: what the runner sends before its approach
    rep.phase(wrench=None, wrench_planned=None, deflection_mm=None, test_id=2, phase="approach")
    text = _panel_text(rep)
    assert text.count("- (not measured yet in this test)") == 2 and "2200.0" not in text
    rep.phase(phase="apply_load", wrench_planned=np.array([0, 1000, 0, 0, 0, 0.0]))
    assert "[0.0 1000.0 0.0 0.0 0.0 0.0] N, N m (planned)" in _panel_text(rep)
    assert all(len(line) <= 80 for line in _panel_text(rep).splitlines())


def test_a_ctrl_c_while_a_frame_is_drawn_waits_for_the_frame():
    hits = []
    with pytest.raises(KeyboardInterrupt):
        with interrupt_after():
            os.kill(os.getpid(), signal.SIGINT)
            hits.append("after the signal")  # still running: the frame is finished
    assert hits == ["after the signal"]
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    # nested: the inner block leaves the outer one's handler in place
    with pytest.raises(KeyboardInterrupt):
        with interrupt_after():
            with interrupt_after():
                os.kill(os.getpid(), signal.SIGINT)
            hits.append("inner done")
    assert hits[-1] == "inner done"


def test_interrupted_panel_update_draws_whole_frames_then_closes(monkeypatch):
    rep, out = _reporter()
    rep.start({"run_dir": "run"})
    original = rep.live.update

    def update(*args, **kwargs):
        os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C in the middle of drawing
        return original(*args, **kwargs)

    monkeypatch.setattr(rep.live, "update", update)
    with pytest.raises(KeyboardInterrupt):
        rep.phase(test_id=3, phase="tare", done=2, total=3)
    drawn = out.getvalue()
    # the frame that was being drawn is complete: its last row is there
    assert drawn.rstrip().endswith("s remaining") or "s remaining" in drawn.splitlines()[-1]
    rep.finish("aborted", "interrupted by the operator (Ctrl-C)",
               {"run_dir": "run", "done": 2, "total": 3, "ok": 2, "failed": 0,
                "safe_state": "robot stopped; load removed",
                "resume": "campaign acquire --resume run --fake"})
    tail = out.getvalue()[len(drawn):]
    assert rep.live is None
    text = [line for line in tail.replace("\r", "\n").splitlines() if line.strip()]
    assert text[-1].endswith("to continue: campaign acquire --resume run --fake")
    assert "after the stop: robot stopped; load removed" in text[-2]
    assert "run aborted: interrupted by the operator (Ctrl-C) (2/3 measurements" in tail


def _events(path, records):
    with (path / "events.jsonl").open("w") as f:
        for r in records:
            f.write(json.dumps(r) + "\n")


def test_safe_state_and_counts_come_from_the_run_directory(tmp_path):
    (tmp_path / "tests.csv").write_text("test_id,repeat,status\n1,1,ok\n1,2,failed\n2,1,ok\n")
    _events(tmp_path, [
        {"event": "load_applied", "session": 1}, {"event": "load_removed", "session": 1},
        {"event": "load_applied", "session": 2}, {"event": "interrupt", "session": 2},
        {"event": "robot_stopped", "session": 2},
        {"event": "load_removed", "session": 2, "reason": "safe stop"}])
    assert safe_state(tmp_path, 2) == "robot stopped; load removed"
    assert safe_state(tmp_path, 1) is None  # session 1 ended normally
    summary = ending(tmp_path, 2, "aborted", fake=True, total=15)
    assert (summary["done"], summary["ok"], summary["failed"], summary["total"]) == (3, 2, 1,
                                                                                     15)
    assert summary["resume"] == f"campaign acquire --resume {tmp_path} --fake"
    lines = final_lines("aborted", "interrupted by the operator (Ctrl-C)", summary)
    assert lines[0].startswith("run aborted: interrupted by the operator (Ctrl-C) "
                               "(3/15 measurements: 2 ok, 1 failed)")
    # a load left on the tool, a robot whose stop failed, a stop not recorded
    _events(tmp_path, [
        {"event": "load_applied", "session": 1}, {"event": "abort", "session": 1},
        {"event": "fault", "session": 1, "reason": "could not stop the robot: timeout"},
        {"event": "load_left", "session": 1, "reason": "manual load: remove it by hand"}])
    assert safe_state(tmp_path, 1) == (
        "ROBOT NOT STOPPED (could not stop the robot: timeout): use the controller's stop; "
        "LOAD STILL APPLIED (manual load: remove it by hand)")
    _events(tmp_path, [{"event": "load_applied", "session": 1},
                       {"event": "interrupt", "session": 1}])
    assert safe_state(tmp_path, 1) == (
        "robot stop not recorded in events.jsonl: check the robot; load removal not "
        "recorded in events.jsonl: check the tool")
    _events(tmp_path, [{"event": "interrupt", "session": 1},
                       {"event": "robot_stopped", "session": 1}])
    assert safe_state(tmp_path, 1) == "robot stopped; no load was on the tool"
    assert "resume" not in ending(tmp_path, 1, "complete", fake=False, total=3)


def test_ctrl_c_on_an_80_column_terminal_erases_the_panel_and_ends_with_the_resume_line(
        small_plan, tmp_path):
    """The real command in a pseudo-terminal: after Ctrl-C the panel is wiped whole and
    the last lines are the closing ones."""
    import fcntl
    import pty
    import select
    import struct
    import subprocess
    import sys
    import termios
    import time

    from tests.acquire.conftest import ROOT

    run = tmp_path / "run"
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    proc = subprocess.Popen([sys.executable, "-m", "campaign", "acquire", "--plan",
                             str(small_plan), "--fake", "--yes", "--out", str(run),
                             "--time-scale", "50"], cwd=ROOT, stdin=slave, stdout=slave,
                            stderr=slave, start_new_session=True)
    os.close(slave)
    out, sent, deadline = b"", False, time.monotonic() + 120
    try:
        while time.monotonic() < deadline:
            ready, _, _ = select.select([master], [], [], 0.05)
            if ready:
                try:
                    data = os.read(master, 65536)
                except OSError:
                    break
                if not data:
                    break
                out += data
            if not sent and b"test 1 repeat 1: ok" in out:
                os.killpg(proc.pid, signal.SIGINT)
                sent = True
            if proc.poll() is not None and not ready:
                break
    finally:
        os.close(master)
        if proc.poll() is None:
            proc.kill()
    assert sent and proc.wait(timeout=30) == 1
    text = out.decode(errors="replace")
    stop = text.rindex("\x1b[?25h")  # the panel stopped (cursor shown again)
    frame, after = text[:stop], text[stop:]
    assert frame.rstrip().endswith("s remaining")  # its last frame was whole
    rows = frame[frame.rindex("run  "):].count("\r\n")
    # every row of it erased (cursor up + erase line), then only the closing lines
    assert after.count("\x1b[1A\x1b[2K") == rows
    plain = re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", after).replace("\r", "")
    lines = []  # logical lines: a wrapped one continues under a two-space indent
    for line in plain.splitlines():
        if line.startswith("  ") and lines:
            lines[-1] += " " + line.strip()
        elif line.strip():
            lines.append(line)
    assert all(len(line) <= 80 for line in plain.splitlines())
    assert lines[0].startswith("run aborted: interrupted by the operator (Ctrl-C) (")
    assert lines[-2].startswith("after the stop: robot stopped; ")
    assert lines[-1] == f"to continue: campaign acquire --resume {run} --fake"
    assert "deflection" not in plain
