"""A seeded ``acquire --fake`` gives the same tests.csv every time.

Every reading of the simulated lab draws its noise from a generator seeded by
(seed, instrument, test, repeat, attempt, phase, window, sample), and the
settling ends exactly six time constants after a change, so neither the order
in which the fakes' threads run, the number of settling reads nor the time scale
changes a measured number. What differs between two runs is the wall-clock time stamp
``t_utc`` (the last column) and, in samples.jsonl, the time stamps and the
number of settling reads.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

from drivers.sim.noise import NoiseStreams
from drivers.sim.settings import LabSettings
from drivers.sim.world import SETTLED_AFTER, World

pytestmark = pytest.mark.timeout(240)


def _without_time_stamps(text: str) -> list[str]:
    lines = text.splitlines()
    assert lines[0].endswith(",t_utc"), lines[0]
    return [line.rsplit(",", 1)[0] for line in lines]


def test_seeded_fake_acquisition_gives_the_same_tests_csv_twice(kr240_plan, make_variant,
                                                                tmp_path, cli):
    plan = make_variant(kr240_plan, tmp_path / "plan", repeats=1)
    from campaign.cli import main

    # two time scales: the numbers follow neither the wall clock nor the threads' order;
    # one run in a process of its own, one in this process (nothing carried by a process)
    done = cli("acquire", "--plan", str(plan), "--fake", "--yes", "--quiet", "--out",
               str(tmp_path / "a"), "--time-scale", "200")
    assert done.returncode == 0, done.stderr
    assert main(["acquire", "--plan", str(plan), "--fake", "--yes", "--quiet", "--out",
                 str(tmp_path / "b"), "--time-scale", "120"]) == 0
    texts = [(tmp_path / name / "tests.csv").read_text() for name in "ab"]
    a, b = (_without_time_stamps(t) for t in texts)
    assert len(a) == 6 and all(",ok," in row for row in a[1:]), a
    assert a == b  # every byte but the time stamps
    assert texts[0] != texts[1]  # the time stamps are the wall clock's
    # the numbers carry the lab's noise (not a noise-free lab that repeats trivially):
    # the tracker's repeatability is of the order of its 30 um noise, never 0
    rep = [float(r.split(",")[23]) for r in a[2:] if r.split(",")[23]]
    header = a[0].split(",")
    assert header[23] == "repeatability_mm"
    assert all(0 < v < 0.2 for v in rep), rep


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
