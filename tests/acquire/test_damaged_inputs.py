"""Damaged plans and run directories: a one-line error (exit 2) naming the place, never a
traceback, never silently accepted; nothing already recorded is lost or changed."""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from analysis.errors import InputError
from campaign.acquire.progress import QuietReporter
from campaign.acquire.rundir import RunDir
from campaign.acquire.session import AcquireOptions, acquire
from campaign.cli import main
from tests.refusal import assert_refused, outside_dir, tree


def run_cli(capsys, *args: str) -> tuple[int, str]:
    """``campaign ARGS`` in this process: (exit status, stderr)."""
    code = main(list(args))
    return code, capsys.readouterr().err


def _fake(plan, out, resume=None, reporter=None):
    # the lab's clock 25 x the wall clock (not 100 x): the same readings, and the fake
    # F/T sensor's records keep within the driver's 1 s deadline on a loaded machine (at
    # load ~20 under -n 2, 100 x gave "no RDT record within 1.0 s" and 24 errors)
    return acquire(None if resume else plan, None if resume else out, resume,
                   AcquireOptions(fake=True, assume_yes=True, time_scale=25.0),
                   reporter or QuietReporter(), say=lambda s: None)


def _digest(run: Path) -> dict[str, str]:
    """SHA-256 of every file of a run directory (to show nothing changed)."""
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(run.iterdir()) if p.is_file() and p.name != ".lock"}


@pytest.fixture(scope="module")
def one_run(kr240_plan, tmp_path_factory) -> Path:
    """A finished run of 2 tests x 2 repeats in the simulated lab (copied by each test)."""
    import pandas as pd

    base = tmp_path_factory.mktemp("one_run")
    plan = base / "plan"
    shutil.copytree(kr240_plan, plan)
    df = pd.read_csv(plan / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df.iloc[:2].assign(repeats=2).to_csv(plan / "plan.csv", index=False)
    outcome = _fake(plan, base / "run")
    assert outcome.status == "complete", outcome.reason
    return base / "run"


@pytest.fixture
def run_copy(one_run, tmp_path) -> Path:
    dest = tmp_path / "run"
    shutil.copytree(one_run, dest)
    (dest / ".lock").unlink(missing_ok=True)
    return dest


# -- plans ----------------------------------------------------------------------------------

def _edit_cell(plan: Path, line: int, column: str, value: str) -> None:
    lines = (plan / "plan.csv").read_text().splitlines()
    header = lines[0].split(",")
    cells = lines[line - 1].split(",")
    cells[header.index(column)] = value
    lines[line - 1] = ",".join(cells)
    (plan / "plan.csv").write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize("damage, message", [
    (lambda p: (p / "plan.csv").write_bytes(b""), "plan.csv: empty file"),
    (lambda p: (p / "plan.csv").write_bytes(bytes(range(256)) * 4),
     "plan.csv: plan is not UTF-8 text (binary, or another encoding): byte 128 on line 2"),
    (lambda p: (p / "plan.csv").write_bytes((p / "plan.csv").read_text().encode("utf-16")),
     "plan.csv: plan is UTF-16 text; save it as UTF-8"),
    (lambda p: (p / "plan.csv").write_bytes((p / "plan.csv").read_text().encode("utf-16-le")),
     "plan.csv: plan is not text (NUL byte on line 1"),
    (lambda p: _edit_cell(p, 3, "test", "two"), "line 3, column test: 'two' is not a finite"),
    (lambda p: _edit_cell(p, 2, "test", "1.5"), "line 2, column test: 1.5 is not a whole"),
    (lambda p: _edit_cell(p, 2, "repeats", "2.7"),
     "line 2, column repeats: 2.7 is not a whole number"),
    (lambda p: _edit_cell(p, 4, "repeats", "1e9"),
     "line 4, column repeats: 1e+09 is outside 1..1000"),
    (lambda p: _edit_cell(p, 3, "test", "1"), "line 3, column test: test 1 already on line 2"),
    (lambda p: _edit_cell(p, 5, "fz_N", "nan"), "line 5, column fz_N: 'nan' is not a finite"),
    (lambda p: (p / "plan.csv").write_text("test,pose\n1,2\n"), "plan table lacks columns"),
    (lambda p: (p / "plan.csv").write_text((p / "plan.csv").read_text().splitlines()[0]
                                           + "\n"), "the plan has no tests"),
    (lambda p: (p / "plan.csv").write_text('"a,b\n1,2\n'), "not a CSV table"),
    (lambda p: (p / "protocol.toml").write_bytes(
        (p / "protocol.toml").read_text().encode("utf-16")),
     "protocol.toml: protocol file is UTF-16 text; save it as UTF-8"),
    (lambda p: (p / "protocol.toml").write_bytes(b"\x00\x01\x02\xff" * 50),
     "protocol.toml: protocol file is not UTF-8 text"),
])
def test_damaged_plan_is_one_line_error(kr240_plan, tmp_path, capsys, damage, message):
    plan = tmp_path / "plan"
    shutil.copytree(kr240_plan, plan)
    damage(plan)
    code, err = run_cli(capsys, "acquire", "--plan", str(plan), "--dry-run")
    assert code == 2
    assert message in err
    assert err.startswith("error: ") and err.count("\n") == 1  # one line, no traceback


def test_pendant_column_that_disagrees_with_the_model_is_refused(kr240_plan, tmp_path, capsys):
    plan = tmp_path / "plan"
    shutil.copytree(kr240_plan, plan)
    from campaign.planning.plan_output import read_plan
    from campaign.protocol_robot import protocol_robot

    protocol, df = read_plan(plan)
    q = np.radians(df[[f"q{j}_model_deg" for j in range(1, 7)]].to_numpy()[1])
    ctrl = np.degrees(protocol_robot(protocol).to_controller(q))[2]  # A3 of test 2
    _edit_cell(plan, 3, "q3_ctrl_deg", f"{ctrl + 5:.3f}")
    code, err = run_cli(capsys, "acquire", "--plan", str(plan), "--dry-run")
    assert code == 2
    assert "line 3 (test 2), column q3_ctrl_deg" in err
    assert f"is {ctrl:.3f} deg in the controller convention" in err
    assert "pendant and model columns disagree" in err
    # within the 3-decimal rounding of the file the columns agree
    _edit_cell(plan, 3, "q3_ctrl_deg", f"{ctrl + 0.001:.3f}")
    code, _ = run_cli(capsys, "acquire", "--plan", str(plan), "--dry-run")
    assert code == 0


def test_non_utf8_robot_file_is_one_line_error(tmp_path):
    from analysis.model.robots import load_robot

    bad = tmp_path / "robot.toml"
    bad.write_bytes('name = "é"\n'.encode("latin-1"))
    with pytest.raises(InputError) as err:
        load_robot(str(bad))
    assert str(err.value) == (f"{bad}: robot file is not UTF-8 text (binary, or another "
                              "encoding): byte 8 on line 1")


# -- the dry run: bounded and timed -----------------------------------------------------------

def test_move_time_of_the_trapezoidal_profile():
    from campaign.acquire.preflight import move_time

    # reaches the speed: d/v + v/a; does not: 2 sqrt(d/a)
    assert move_time(np.array([1.0]), 1.0, 2.0)[0] == pytest.approx(1.5)
    assert move_time(np.array([0.1]), 1.0, 2.0)[0] == pytest.approx(2 * np.sqrt(0.05))
    # continuous at the switch (d = v^2/a) and checked against a stepped integration
    assert move_time(np.array([0.5]), 1.0, 2.0)[0] == pytest.approx(1.0)
    dt, v, x, t = 1e-5, 0.0, 0.0, 0.0
    while x < 0.8:  # accelerate until the remaining distance needs braking
        brake = v * v / (2 * 2.0)
        v = max(min(v + 2.0 * dt, 1.0) if 0.8 - x > brake else v - 2.0 * dt, 1e-9)
        x += v * dt
        t += dt
    assert move_time(np.array([0.8]), 1.0, 2.0)[0] == pytest.approx(t, abs=2e-3)


def test_dry_run_shows_the_planned_duration(kr240_plan, tmp_path, capsys):
    from campaign.acquire.preflight import move_time, planned_tests
    from campaign.acquire.session import _settle_rule
    from campaign.planning.plan_output import read_plan
    from campaign.protocol_robot import protocol_robot

    code = main(["acquire", "--plan", str(kr240_plan), "--dry-run"])
    out = capsys.readouterr().out
    assert code == 0
    line = next(s for s in out.splitlines() if s.startswith("planned duration"))
    # independent sum: approach -> test for each measurement, repeats back to back
    protocol, plan = read_plan(kr240_plan)
    robot = protocol_robot(protocol)
    tests = planned_tests(protocol, plan, robot)
    speed = protocol.safety.max_joint_speed_deg_s * np.pi / 180
    acc = protocol.safety.max_joint_acceleration_deg_s2 * np.pi / 180
    targets = [q for t in tests for _ in range(t.repeats) for q in (t.q_approach, t.q)]
    t_motion = sum(move_time(np.max(np.abs(b - a)), speed, acc)
                   for a, b in zip(targets[:-1], targets[1:], strict=True))
    rule = _settle_rule(protocol, 1.0, 0.5)
    n = sum(t.repeats for t in tests)
    t_settle = 3 * n * (rule.window - 1) * rule.interval
    assert n == 15 and t_settle == pytest.approx(3 * 15 * 3.6)
    assert f"({t_motion:.0f} s of motion" in line
    assert f", {t_settle:.0f} s = {t_settle / 60:.0f} min of settling" in line
    assert f"at least {t_motion + t_settle:.0f} s = " in line


def test_the_largest_repeat_count_is_planned_and_counted(kr240_plan, tmp_path, capsys):
    from campaign.acquire.preflight import motion_limits, planned_duration, planned_tests
    from campaign.planning.plan_output import MAX_REPEATS, read_plan
    from campaign.protocol_robot import protocol_robot

    plan = tmp_path / "plan"
    shutil.copytree(kr240_plan, plan)
    _edit_cell(plan, 2, "repeats", str(MAX_REPEATS))
    code = main(["acquire", "--plan", str(plan), "--dry-run"])
    assert code == 0  # the bound itself is accepted, and its duration is shown
    assert "planned duration: at least" in capsys.readouterr().out
    protocol, df = read_plan(plan)
    tests = planned_tests(protocol, df, protocol_robot(protocol))
    n, t_motion, _ = planned_duration(tests, set(), motion_limits(protocol), 0.0)
    assert n == MAX_REPEATS + 4 * 3 and t_motion > 0
    # resuming after test 1's first 999 repeats leaves 1 + 12 measurements
    n, _, _ = planned_duration(tests, {(tests[0].test_id, r) for r in range(1, MAX_REPEATS)},
                               motion_limits(protocol), 0.0)
    assert n == 13


# -- run directories at --resume and analyze ---------------------------------------------------

def _replace_line(path: Path, line: int, text: str) -> None:
    lines = path.read_text().splitlines(keepends=True)
    lines[line - 1] = text
    path.write_text("".join(lines))


@pytest.mark.parametrize("damage, message", [
    (lambda r: (r / "metadata.json").write_bytes(b"\xff\xd8\xff\xe0garbage"),
     "metadata.json: metadata.json is not UTF-8 text"),
    (lambda r: (r / "metadata.json").write_text("{\"status\": "),
     "metadata.json: not valid JSON (line 1, column 12)"),
    (lambda r: (r / "metadata.json").write_text("[1, 2, 3]\n"),
     "metadata.json: expected a JSON object, found a list"),
    (lambda r: _replace_line(r / "tests.csv", 3, "%%garbage%%\n"),
     "tests.csv: line 3: not a test row"),
    (lambda r: (r / "tests.csv").write_text((r / "tests.csv").read_text()
                                            + (r / "tests.csv").read_text().splitlines()[2]
                                            + "\n"),
     "tests.csv: lines 3 and 6: test 1 repeat 2 recorded twice"),
    (lambda r: (r / "protocol.toml").write_text((r / "protocol.toml").read_text()
                                                + "\n# edited\n"),
     "protocol.toml does not match protocol_sha256 of metadata.json"),
    (lambda r: (r / "plan.csv").write_text((r / "plan.csv").read_text() + "\n"),
     "plan.csv does not match plan_sha256 of metadata.json"),
])
def test_damaged_run_is_refused_at_resume_and_nothing_changes(run_copy, capsys, damage,
                                                              message):
    damage(run_copy)
    before = _digest(run_copy)
    code, err = run_cli(capsys, "acquire", "--resume", str(run_copy), "--fake", "--yes",
                        "--quiet")
    assert code == 2
    assert message in err
    assert err.startswith("error: ") and err.count("\n") == 1
    assert _digest(run_copy) == before  # refused before anything was written


@pytest.mark.parametrize("damage, message", [
    (lambda r: (r / "metadata.json").write_bytes(b"\xff\xd8\xff\xe0garbage"),
     "metadata.json is not UTF-8 text"),
    (lambda r: (r / "metadata.json").write_text("[1, 2, 3]\n"),
     "expected a JSON object, found a list"),
    (lambda r: (r / "tests.csv").write_text((r / "tests.csv").read_text()
                                            + (r / "tests.csv").read_text().splitlines()[2]
                                            + "\n"),
     "lines 3 and 6: test 1 repeat 2 recorded twice"),
    (lambda r: (r / "protocol.toml").write_text((r / "protocol.toml").read_text()
                                                + "\n# edited\n"),
     "protocol.toml does not match protocol_sha256 of metadata.json"),
])
def test_damaged_run_is_refused_by_analyze(run_copy, capsys, damage, message):
    damage(run_copy)
    code, err = run_cli(capsys, "analyze", str(run_copy), "--no-report")
    assert code == 2
    assert message in err and err.count("\n") == 1


def test_creation_killed_midway_leaves_nothing_to_resume_and_the_name_free(tmp_path):
    import signal
    import subprocess
    import sys

    out = tmp_path / "run"
    script = (
        "import os, signal, sys\n"
        "from campaign.acquire import rundir\n"
        "os.rename = lambda a, b: os.kill(os.getpid(), signal.SIGKILL)\n"
        f"rundir.RunDir.create(rundir.Path({str(out)!r}), {{'fake': True}}, 'protocol.toml',"
        " 'x = 1\\n', 'test\\n')\n")
    proc = subprocess.run([sys.executable, "-c", script], cwd=Path(__file__).parents[2],
                          capture_output=True, timeout=60)
    assert proc.returncode == -signal.SIGKILL
    assert not out.exists()  # killed just before the rename: no half-made run
    stale = list(tmp_path.glob(".run.creating-*"))
    assert len(stale) == 1 and (stale[0] / "plan.csv").is_file()
    run = RunDir.create(out, {"fake": True}, "protocol.toml", "x = 1\n", "test\n")
    run.close()
    assert sorted(p.name for p in out.iterdir()) == [  # .lock removed at close
        "events.jsonl", "metadata.json", "plan.csv", "protocol.toml", "samples.jsonl",
        "tests.csv"]
    assert not list(tmp_path.glob(".run.creating-*"))  # the stale one was removed


def test_two_creations_of_one_run_directory_exclude_each_other(tmp_path, monkeypatch):
    import os

    out = tmp_path / "run"
    real_rename = os.rename
    temp_names = []

    def rename_after_the_other(src, dst):
        # the other process creates the same run between our check and our rename
        temp_names.append(Path(src).name)
        monkeypatch.setattr(os, "rename", real_rename)
        other = RunDir.create(out, {"who": "other"}, "protocol.toml", "x = 1\n", "test\n")
        other.close()
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", rename_after_the_other)
    with pytest.raises(InputError, match="created by another process meanwhile"):
        RunDir.create(out, {"who": "first"}, "protocol.toml", "x = 2\n", "test\n")
    assert json.loads((out / "metadata.json").read_text())["who"] == "other"
    assert (out / "protocol.toml").read_text() == "x = 1\n"
    assert not list(tmp_path.glob(".run.creating-*"))  # the loser cleaned up
    assert temp_names and temp_names[0].startswith(".run.creating-")


# -- writing: links, read-only and full disks, finished runs ---------------------------------

@pytest.fixture
def outside(tmp_path) -> Path:
    return outside_dir(tmp_path)


def test_one_run_leaves_no_lock_behind(one_run):
    assert not (one_run / ".lock").exists()
    assert not [p for p in one_run.iterdir() if p.name.endswith(".tmp")]


@pytest.mark.parametrize("target", ["victim.txt", "missing", "dir"])
def test_acquire_out_onto_a_link_is_refused_before_anything_starts(kr240_plan, tmp_path,
                                                                    capsys, outside, target):
    link = tmp_path / "run"
    link.symlink_to(outside / target)
    assert_refused(capsys, ["acquire", "--plan", kr240_plan, "--out", link, "--fake", "--yes",
                            "--quiet"],
                   f"run: is a symbolic link (to {outside / target}); refusing to write "
                   "through it", watch=[outside])
    assert not (outside / "missing").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["outside", "run"]


@pytest.mark.parametrize("name", ["tests.csv", "samples.jsonl", "events.jsonl", ".lock",
                                  "metadata.json", "tests.meta.json", "samples.parquet"])
def test_resume_refuses_a_link_in_the_run_and_writes_nothing(run_copy, capsys, outside, name):
    import os

    if os.path.lexists(run_copy / name):
        (run_copy / name).unlink()
    (run_copy / name).symlink_to(outside / "victim.txt")
    before, outside_before = tree(run_copy), tree(outside)
    code, err = run_cli(capsys, "acquire", "--resume", str(run_copy), "--fake", "--yes",
                        "--quiet")
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"error: {run_copy / name}: is a symbolic link")
    assert tree(run_copy) == before and tree(outside) == outside_before


def test_analyze_run_refuses_a_linked_analysis_directory_or_file(run_copy, capsys, outside):
    (run_copy / "analysis").symlink_to(outside / "dir")
    before = tree(outside)
    code, err = run_cli(capsys, "analyze", str(run_copy), "--no-report")
    assert code == 2 and err == (f"error: {run_copy / 'analysis'}: is a symbolic link (to "
                                 f"{outside / 'dir'}); refusing to write through it: remove "
                                 "the link or give another path\n")
    (run_copy / "analysis").unlink()
    (run_copy / "analysis").mkdir()
    (run_copy / "analysis" / "report.html").symlink_to(outside / "victim.txt")
    code, err = run_cli(capsys, "analyze", str(run_copy), "--no-report", "--force")
    assert code == 2 and "analysis/report.html: is a symbolic link" in err
    assert err.count("\n") == 1
    assert tree(outside) == before
    assert sorted(p.name for p in (run_copy / "analysis").iterdir()) == ["report.html"]


def test_analyze_of_a_run_refuses_its_earlier_analysis_unless_force(run_copy, capsys):
    assert run_cli(capsys, "analyze", str(run_copy), "--no-report")[0] == 0
    results = run_copy / "analysis" / "results.json"
    first = results.read_bytes()
    code, err = run_cli(capsys, "analyze", str(run_copy), "--no-report")
    assert code == 2 and err.count("\n") == 1
    assert "not empty; choose another or add --force to replace its contents" in err
    assert results.read_bytes() == first
    assert run_cli(capsys, "analyze", str(run_copy), "--no-report", "--force")[0] == 0
    assert not [p for p in run_copy.iterdir() if p.name.startswith(".analysis.")]


def test_resuming_a_complete_run_starts_nothing_and_asks_nothing(run_copy, capsys,
                                                                 monkeypatch):
    import io
    import sys

    import campaign.acquire.session as session

    def no_lab(*args, **kwargs):
        raise AssertionError("the lab was started for a complete run")

    monkeypatch.setattr(session, "open_instruments", no_lab)
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))  # a question would be refused
    before = _digest(run_copy)
    code = main(["acquire", "--resume", str(run_copy), "--fake", "--quiet"])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert captured.out == ""  # the final line goes to stderr with --quiet
    assert captured.err == (f"run complete: nothing to resume: all 4 planned measurements are "
                            f"in tests.csv; nothing connected, nothing moved (4/4 measurements: "
                            f"4 ok, 0 failed) -> {run_copy}\n")
    assert _digest(run_copy) == before and not (run_copy / ".lock").exists()


def test_a_finished_run_that_still_says_running_is_completed_without_motion(run_copy, capsys,
                                                                            monkeypatch):
    import campaign.acquire.session as session

    monkeypatch.setattr(session, "open_instruments", lambda *a, **k: 1 / 0)
    meta = json.loads((run_copy / "metadata.json").read_text())
    (run_copy / "metadata.json").write_text(json.dumps(dict(meta, status="running")))
    (run_copy / "samples.parquet").unlink()
    code = main(["acquire", "--resume", str(run_copy), "--fake", "--yes", "--quiet"])
    assert code == 0 and "nothing to resume" in capsys.readouterr().err
    assert json.loads((run_copy / "metadata.json").read_text())["status"] == "complete"
    assert (run_copy / "samples.parquet").is_file()


def test_resume_on_a_read_only_file_system_is_one_line_and_exit_1(run_copy, capsys,
                                                                  monkeypatch):
    import errno
    import os

    from campaign.acquire import rundir

    real_open = os.open

    def read_only_open(path, flags, *args, **kwargs):
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(rundir.os, "open", read_only_open)
    assert_refused(capsys, ["acquire", "--resume", run_copy, "--fake", "--yes", "--quiet"],
                   f"error: cannot write .lock in {run_copy}: Read-only file system; "
                   "nothing moved", watch=[run_copy], code=1)


def _small_plan(kr240_plan, tmp_path) -> Path:
    import pandas as pd

    plan = tmp_path / "plan"
    shutil.copytree(kr240_plan, plan)
    df = pd.read_csv(plan / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df.iloc[:2].assign(repeats=1).to_csv(plan / "plan.csv", index=False)
    return plan


def test_a_run_directory_made_unwritable_mid_run_is_one_line_and_exit_1(kr240_plan, tmp_path,
                                                                        capsys, monkeypatch):
    import errno
    import os
    import tempfile

    from campaign.acquire import rundir

    plan = _small_plan(kr240_plan, tmp_path)
    out = tmp_path / "run"
    real_mkstemp, real_row = tempfile.mkstemp, rundir.RunDir.test_row
    state = {"rows": 0}

    def test_row(self, row):
        real_row(self, row)
        state["rows"] += 1

    def mkstemp(*args, **kwargs):
        if state["rows"]:  # after the first test: chmod a-w on the run directory
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), kwargs.get("dir"))
        return real_mkstemp(*args, **kwargs)

    monkeypatch.setattr(rundir.RunDir, "test_row", test_row)
    monkeypatch.setattr(tempfile, "mkstemp", mkstemp)
    code = main(["acquire", "--plan", str(plan), "--out", str(out), "--fake", "--yes",
                 "--quiet", "--time-scale", "100"])
    captured = capsys.readouterr()
    assert code == 1
    assert "Traceback" not in captured.out + captured.err and captured.out == ""
    line = captured.err
    assert line.count("\n") == 1 and line.startswith("run complete: metadata.json still says")
    assert f"metadata.json still says running (cannot write metadata.json in {out}: " \
           "Permission denied): resuming the run records it" in line
    assert "the Parquet exports could not be written" in line
    # what could be recorded is: every row, and the status in events.jsonl
    assert finished_rows(out) == 2
    last = json.loads((out / "events.jsonl").read_text().splitlines()[-1])
    assert last["event"] == "status" and last["status"] == "complete"
    assert json.loads((out / "metadata.json").read_text())["status"] == "running"
    assert not [p.name for p in out.iterdir() if ".tmp" in p.name or p.name == ".lock"]


def finished_rows(run: Path) -> int:
    from campaign.acquire.rundir import finished_tests

    return len(finished_tests(run))


def test_a_full_disk_at_the_parquet_export_leaves_no_temporary_and_says_so(kr240_plan,
                                                                           tmp_path, capsys,
                                                                           monkeypatch):
    import errno
    import os

    import pandas as pd

    plan = _small_plan(kr240_plan, tmp_path)
    out = tmp_path / "run"
    real = pd.DataFrame.to_parquet

    def to_parquet(self, path, *args, **kwargs):
        if Path(path).name.startswith(".samples.parquet."):
            Path(path).write_bytes(b"PAR1 half")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, path, *args, **kwargs)

    monkeypatch.setattr(pd.DataFrame, "to_parquet", to_parquet)
    code = main(["acquire", "--plan", str(plan), "--out", str(out), "--fake", "--yes",
                 "--quiet", "--time-scale", "100"])
    captured = capsys.readouterr()
    assert code == 1 and captured.out == "" and "Traceback" not in captured.err
    assert captured.err.count("\n") == 1
    assert captured.err.startswith("run complete: the Parquet exports could not be written "
                                   "(No space left on device); every measurement "
                                   "is in tests.csv and samples.jsonl")
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["status"] == "complete" and meta["parquet_exported"] is False
    assert "Parquet exports could not be written" in meta["reason"]
    assert not (out / "samples.parquet").exists()
    assert not [p.name for p in out.iterdir() if ".tmp" in p.name]
    assert finished_rows(out) == 2 and (out / "samples.jsonl").stat().st_size > 0
    monkeypatch.setattr(pd.DataFrame, "to_parquet", real)
    # space is back: a resume writes the exports without starting anything
    code = main(["acquire", "--resume", str(out), "--fake", "--yes", "--quiet"])
    assert code == 0 and "nothing to resume" in capsys.readouterr().err
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["status"] == "complete" and meta["parquet_exported"] is True
    assert meta["reason"] == ""
    assert len(pd.read_parquet(out / "samples.parquet")) == sum(
        1 for _ in (out / "samples.jsonl").open())
