"""A seeded ``acquire --fake`` (and ``campaign demo``) gives the same tests.csv, byte for byte.

Every reading of the simulated lab draws its noise from a generator seeded by
(seed, instrument, test, repeat, attempt, phase, window, sample), the settling ends
exactly six time constants after a change, and the readings are stamped by the lab's
own clock (:mod:`campaign.acquire.clock`: from 2000-01-01T00:00:00 UTC, advanced by
simulated motion, settling and sampling durations only), so neither the order in which
the fakes' threads run, the number of settling reads, the time scale nor a ``kill -9``
and ``--resume`` changes a byte of tests.csv. What differs between two runs: the
wall-clock records (metadata.json ``started_utc``, ``ended_utc``, ``sessions``, the
lab's port numbers, ``command``; events.jsonl) and, in samples.jsonl, the number of
settling reads.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from campaign.acquire.clock import SIM_EPOCH_UTC
from drivers.sim.noise import NoiseStreams
from drivers.sim.settings import LabSettings
from drivers.sim.world import SETTLED_AFTER, World
from tests.acquire.conftest import ROOT, variant

pytestmark = pytest.mark.timeout(240)


def _acquire(args: list[str]) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "campaign", "acquire", *args, "--fake",
                             "--yes", "--quiet"], cwd=ROOT, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)


def _done(proc: subprocess.Popen) -> None:
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err


@pytest.fixture(scope="module")
def seeded_run(kr240_plan, tmp_path_factory) -> tuple[Path, Path]:
    """(plan, run) of the KR240-2 plan with one repeat (5 measurements) acquired on the
    simulated lab at time scale 200, uninterrupted."""
    base = tmp_path_factory.mktemp("repro")
    plan = variant(kr240_plan, base / "plan", repeats=1)
    _done(_acquire(["--plan", str(plan), "--out", str(base / "a"), "--time-scale", "200"]))
    return plan, base / "a"


def test_seeded_fake_acquisition_gives_the_same_tests_csv_twice(seeded_run, tmp_path):
    plan, run_a = seeded_run
    # another time scale: the numbers and stamps follow neither the wall clock nor the
    # threads' order
    _done(_acquire(["--plan", str(plan), "--out", str(tmp_path / "b"), "--time-scale", "120"]))
    a = (run_a / "tests.csv").read_bytes()
    assert a == (tmp_path / "b" / "tests.csv").read_bytes()
    rows = a.decode().splitlines()
    header = rows[0].split(",")
    assert len(rows) == 6 and all(",ok," in row for row in rows[1:]), rows
    # the stamps are the lab's clock: after its epoch, increasing, a few tens of seconds
    # of robot time per measurement (3 settlings of 6.6 s, motions at 10 deg/s or more)
    assert header[-1] == "t_utc"
    from datetime import datetime

    epoch = datetime.fromisoformat(SIM_EPOCH_UTC)
    t = np.array([(datetime.fromisoformat(r.split(",")[-1]) - epoch).total_seconds()
                  for r in rows[1:]])
    assert t[0] > 3 * 6.6 and np.all(np.diff(t) > 3 * 6.6) and t[-1] < 5 * 120, t
    meta = json.loads((run_a / "metadata.json").read_text())
    assert meta["time_stamps"]["clock"] == "simulated"
    assert meta["time_stamps"]["epoch_utc"] == SIM_EPOCH_UTC
    assert meta["started_utc"][:4] != "2000"  # the session's wall clock stays
    # the numbers carry the lab's noise (not a noise-free lab that repeats trivially):
    # the tracker's repeatability is of the order of its 30 um noise, never 0
    assert header[23] == "repeatability_mm"
    rep = [float(r.split(",")[23]) for r in rows[2:] if r.split(",")[23]]
    assert all(0 < v < 0.2 for v in rep), rep
    # samples.jsonl: every reading but the settling reads is the same, stamps included
    def readings(run):
        lines = (run / "samples.jsonl").read_text().splitlines()
        out = []
        for line in lines:
            rec = json.loads(line)
            if rec["quantity"] != "point":
                out.append(line)
        return out

    assert readings(run_a) == readings(tmp_path / "b")


def _lines(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


def _kill_in_test(proc: subprocess.Popen, run: Path, rows: int, after: int) -> None:
    """kill -9 ``proc`` ``after`` lines of samples.jsonl after tests.csv has ``rows`` rows."""
    deadline = time.monotonic() + 90
    mark = None
    while time.monotonic() < deadline:
        assert proc.poll() is None, "the run ended before the kill"
        n = _lines(run / "samples.jsonl")
        if mark is None and _lines(run / "tests.csv") - 1 >= rows:
            mark = n
        if mark is not None and n >= mark + after:
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait()
            return
        time.sleep(0.001)
    proc.kill()
    raise AssertionError("acquire did not progress")


def test_kill9_and_resume_gives_the_same_tests_csv(seeded_run, tmp_path):
    plan, run_a = seeded_run
    run = tmp_path / "run"
    # killed twice: in the second measurement (3 readings in, before its load) and 20
    # readings into the fourth, at time scales slow enough to land there
    proc = _acquire(["--plan", str(plan), "--out", str(run), "--time-scale", "100"])
    _kill_in_test(proc, run, rows=1, after=3)
    proc = _acquire(["--resume", str(run), "--time-scale", "150"])
    _kill_in_test(proc, run, rows=3, after=20)
    _done(_acquire(["--resume", str(run), "--time-scale", "200"]))
    meta = json.loads((run / "metadata.json").read_text())
    assert meta["status"] == "complete" and len(meta["sessions"]) == 3
    assert (run / "tests.csv").read_bytes() == (run_a / "tests.csv").read_bytes()


def test_noise_streams_do_not_depend_on_the_order_of_the_threads():
    def draws(order: list[str]) -> dict[str, list[float]]:
        streams = NoiseStreams(7)
        streams.mark(3, 1, 1, "loaded")
        out: dict[str, list[float]] = {"ft": [], "tracker": []}
        for who in order:
            out[who].append(float(streams.generator(who).normal()))
        return out

    one = draws(["ft", "ft", "tracker", "ft", "tracker"])
    two = draws(["tracker", "ft", "tracker", "ft", "ft"])
    assert one == two
    assert len(set(one["ft"])) == 3  # successive samples differ
    # another context, another seed or another window: other numbers
    streams = NoiseStreams(7)
    streams.mark(3, 1, 1, "tare")
    assert float(streams.generator("ft").normal()) != one["ft"][0]
    streams = NoiseStreams(8)
    streams.mark(3, 1, 1, "loaded")
    assert float(streams.generator("ft").normal()) != one["ft"][0]
    streams = NoiseStreams(7)
    streams.mark(3, 1, 1, "loaded")
    streams.generator("ft")
    streams.new_window("ft")
    second_window = float(streams.generator("ft").normal())
    assert second_window not in one["ft"]


def test_world_readings_are_the_same_whatever_other_threads_draw():
    def readings(noisy_neighbour: bool) -> list[np.ndarray]:
        world = World(LabSettings(seed=4, time_scale=1e6, can_interface="virtual"))
        world.apply_load(np.array([0.0, 2000.0, 2000.0, 100.0, 0.0, 0.0]))
        stop = threading.Event()

        def neighbour():
            while not stop.is_set():
                world.sensor_wrench("ati-netft")

        t = threading.Thread(target=neighbour, daemon=True)
        if noisy_neighbour:
            t.start()
        try:
            world.noise_streams.mark(1, 1, 1, "loaded")
            return [world.tracker_pose("emscon") for _ in range(5)]
        finally:
            stop.set()
            if noisy_neighbour:
                t.join()

    quiet, busy = readings(False), readings(True)
    for p, q in zip(quiet, busy, strict=True):
        assert np.array_equal(p, q)
    # tracker noise 10 um per coordinate: successive readings differ by about that
    spread = np.std([p[:3, 3] for p in quiet], axis=0)
    assert np.all((spread > 1e-6) & (spread < 5e-5)), spread


def test_polled_joint_angles_do_not_depend_on_the_number_of_polls():
    # the UR fake polls the world's state every 5 ms: its encoder noise is one draw held
    # per phase, not the n-th sample of a count that follows the wall clock
    def polled(polls: int) -> np.ndarray:
        world = World(LabSettings(seed=5, time_scale=1e6, encoder_noise=2e-6,
                                  can_interface="virtual"))
        world.noise_streams.mark(2, 1, 1, "move")
        for _ in range(polls):
            world.state()
        return np.asarray(world.state()["q"])

    once, many = polled(0), polled(40)
    assert np.array_equal(once, many)
    world = World(LabSettings(seed=5, time_scale=1e6, encoder_noise=2e-6,
                              can_interface="virtual"))
    q_cmd = world._q_cmd.copy()
    # the held noise is the encoder noise (2 urad), and another phase draws another one
    assert 0 < np.max(np.abs(once - q_cmd)) < 6 * 2e-6
    world.noise_streams.mark(2, 1, 1, "loaded")
    other = np.asarray(world.state()["q"])
    assert not np.array_equal(other, once)
    # a request/response fake still reads the next sample of its stream each time
    assert not np.array_equal(world.joint_angles("kvp"), world.joint_angles("kvp"))


def test_settling_is_exactly_over_after_six_time_constants():
    world = World(LabSettings(seed=0, time_scale=1.0, settle_time=0.5, can_interface="virtual"))
    world.apply_load(np.array([0.0, 2000.0, 2000.0, 100.0, 0.0, 0.0]))
    target = world._dq_to.copy()
    t0 = world._t_change
    assert np.array_equal(world._deflection(t0 + SETTLED_AFTER * world.tau), target)
    before = world._deflection(t0 + 5 * world.tau)
    # exponential settling before: 1 - e^-5 of the step reached
    np.testing.assert_allclose(before, target * (1 - np.exp(-5)), rtol=1e-12)


def test_control_channel_mark_sets_the_context_of_the_noise():
    from drivers.sim.control import handle_command

    world = World(LabSettings(seed=9, time_scale=1e6, can_interface="virtual"))
    assert handle_command(world, {"cmd": "mark", "context": [2, 1, 1, "loaded"]}, {})["ok"]
    first = [world.tracker_point(source="geocom") for _ in range(3)]
    world.tracker_point(source="emscon")  # another instrument's draw changes nothing
    assert handle_command(world, {"cmd": "mark", "context": [2, 1, 1, "loaded"]}, {})["ok"]
    again = [world.tracker_point(source="geocom") for _ in range(3)]
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert handle_command(world, {"cmd": "mark", "context": [2, 1, 2, "loaded"]}, {})["ok"]
    assert not np.array_equal(world.tracker_point(source="geocom"), first[0])
    for bad in ([-1], "loaded", [1.5], [True]):
        reply = handle_command(world, {"cmd": "mark", "context": bad}, {})
        assert not reply["ok"] and "context" in reply["error"], reply


#: metadata.json keys that are the session's wall clock or where it ran (lab ports, paths)
WALL_CLOCK_AND_IDENTITY = ("started_utc", "ended_utc", "sessions", "instruments",
                           "plan_source", "protocol_source", "command")


def _demo(out: Path, protocol: Path):
    from campaign.jobs import demo

    result = demo.run(demo.DemoOptions(out=out, protocol=protocol, report=False, tests=3,
                                       candidates=300, time_scale=300))
    assert result.succeeded, result.acquisition.reason
    return result


def test_demo_twice_gives_the_same_bytes_and_another_seed_other_numbers(tmp_path):
    from analysis.report.summary import CampaignInfo, summary_table
    from campaign.protocol import load_protocol
    from campaign.run_format.reader import read_run
    from campaign.run_format.trace import run_trace

    text = (ROOT / "protocols" / "kr240-2.toml").read_text()
    assert text.count("\nseed = 1\n") == 1
    seeds = {}
    for seed in (1, 2):
        seeds[seed] = tmp_path / f"seed{seed}.toml"
        seeds[seed].write_text(text.replace("\nseed = 1\n", f"\nseed = {seed}\n"))
    one, two, other = (tmp_path / n for n in ("one", "two", "other"))
    _demo(one, seeds[1])
    _demo(two, seeds[1])
    _demo(other, seeds[2])
    # byte for byte: the plan, the measurements and every result (the report ID, a hash
    # of the inputs and results, too)
    for name in ("plan/plan.csv", "run/tests.csv", "run/tests.parquet",
                 "run/analysis/results.json", "run/analysis/residuals.csv",
                 "run/analysis/validation.csv"):
        assert (one / name).read_bytes() == (two / name).read_bytes(), name
    # the run's metadata differs in the session's wall-clock records and where it ran only
    meta = [json.loads((d / "run" / "metadata.json").read_text()) for d in (one, two)]
    assert meta[0]["started_utc"] != meta[1]["started_utc"]
    for m in meta:
        for key in WALL_CLOCK_AND_IDENTITY:
            m.pop(key)
    assert meta[0] == meta[1]
    # another seed: the same plan and clock, other noise, other numbers
    assert (one / "plan/plan.csv").read_bytes() == (other / "plan/plan.csv").read_bytes()
    rows = [(d / "run/tests.csv").read_text().splitlines() for d in (one, other)]
    for a, b in zip(rows[0][1:], rows[1][1:], strict=True):
        a, b = a.split(","), b.split(",")
        assert a[:7] == b[:7] and a[-1] == b[-1]  # pose, joint angles, time stamp
        assert all(x != y for x, y in zip(a[13:16], b[13:16], strict=True))  # dx, dy, dz
    k = [json.loads((d / "run/analysis/results.json").read_text()) for d in (one, other)]
    assert all(a != b for a, b in zip(*(r["joint_stiffness_Nm_per_rad"] for r in k),
                                      strict=True))
    # the report's Campaign table says the time stamps are simulated
    run = read_run(one / "run", export=False)
    info = CampaignInfo(source="run", location=str(run.path), robot="KUKA KR240-2",
                        **run_trace(run, load_protocol(one / "run" / "protocol.toml")))
    rows = {r[0]: r[1] for r in summary_table(info).rows}
    assert "SIMULATED lab clock from 2000-01-01T00:00:00Z" in rows["time stamps"], rows


def test_simulated_clock_resumes_exactly_and_refuses_a_bad_stamp(tmp_path):
    from types import SimpleNamespace

    from analysis.errors import InputError
    from campaign.acquire.clock import SimulatedClock, describe
    from campaign.acquire.rundir import TEST_COLUMNS
    from campaign.acquire.session import run_clock
    from campaign.protocol import load_protocol
    from campaign.protocol_robot import protocol_robot

    clock = SimulatedClock(speed=0.5, acceleration=1.0, settle_s=6.6, interval_s=0.4)
    clock.move(np.zeros(6))  # the first motion counts 0
    assert clock.stamp() == SIM_EPOCH_UTC
    clock.move(np.array([0.0, 1.0, 0, 0, 0, 0]))  # 1 rad: 1 / 0.5 + 0.5 / 1 = 2.5 s
    clock.settle_start()
    for _ in range(30):  # more readings than the phase holds: the last ones at its end
        clock.settle_read()
    assert clock.stamp() == "2000-01-01T00:00:09.100000+00:00"
    clock.settle_end()
    clock.wait(0.1)
    again = SimulatedClock(speed=0.5, acceleration=1.0, settle_s=6.6, interval_s=0.4)
    again.resume(clock.stamp(), clock.q_last)
    assert again.now_us == clock.now_us == 9_200_000
    protocol = load_protocol(ROOT / "protocols" / "kr240-2.toml")
    row = dict.fromkeys(TEST_COLUMNS, "1")
    row.update(status="ok", flags="", t_utc="yesterday")
    (tmp_path / "tests.csv").write_text(",".join(TEST_COLUMNS) + "\n"
                                        + ",".join(row[c] for c in TEST_COLUMNS) + "\n")
    run = SimpleNamespace(path=tmp_path, metadata={"time_stamps": {"clock": "simulated"}})
    with pytest.raises(InputError, match=r"tests\.csv: line 2: t_utc 'yesterday' is not an "
                                         "ISO 8601 time"):
        run_clock(run, protocol, protocol_robot(protocol), [], 0.5)
    # a run without time_stamps (hardware, or written before the lab's clock): wall clock
    for meta in ({}, {"time_stamps": describe(False)}):
        run.metadata = meta
        wall = run_clock(run, protocol, protocol_robot(protocol), [], 0.5)
        assert not wall.simulated and wall.stamp(946684800.25) == "2000-01-01T00:00:00.250000+00:00"
