"""Injected faults in the simulated lab: retry, failed rows, clear aborts, data kept."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from campaign.acquire.progress import QuietReporter
from campaign.acquire.session import AcquireOptions, acquire
from drivers.sim.control import LabClient


class Injector(QuietReporter):
    """Reporter that learns the lab's control address and runs ``actions`` on events.

    ``actions``: list of (event name, test_id, attempt or None, callable(client)).
    """

    def __init__(self, actions) -> None:
        super().__init__()
        self.actions = list(actions)
        self.client: LabClient | None = None
        self.events: list[dict] = []

    def start(self, info) -> None:
        super().start(info)
        self.client = LabClient(info["lab"]["control"])

    def event(self, record) -> None:
        self.events.append(record)
        for name, test_id, attempt, action in self.actions:
            if record["event"] == name and record.get("test_id") == test_id and \
                    (attempt is None or record.get("attempt") == attempt):
                action(self.client)

    def finish(self, *args) -> None:
        if self.client is not None:
            self.client.close()


def _run(plan, out, reporter, resume=None):
    return acquire(None if resume else plan, None if resume else out, resume,
                   AcquireOptions(fake=True, assume_yes=True, time_scale=100.0), reporter,
                   say=lambda s: None)


def test_transient_faults_are_retried_and_flagged(small_plan, tmp_path):
    out = tmp_path / "run"
    rep = Injector([
        ("load_applied", 2, 1, lambda c: c.call("fault", device="emscon", fault="beam_lost",
                                                count=1)),
        ("test_done", 2, None, lambda c: c.call("fault", device="kuka-kvp",
                                                 fault="disconnect", count=1)),
    ])
    outcome = _run(small_plan, out, rep)
    assert outcome.status == "complete", outcome.reason
    tests = pd.read_csv(out / "tests.csv", keep_default_na=False)
    assert list(tests.status) == ["ok", "ok", "ok"]
    assert list(tests["flags"]) == ["", "retried", "retried"]
    faults = [e for e in rep.events if e["event"] == "fault"]
    assert [e["test_id"] for e in faults] == [2, 3]
    assert "beam" in faults[0]["reason"] or "10014" in faults[0]["reason"]
    assert faults[1]["phase"] == "approach"  # the controller dropped the link at the move
    # the load was taken off before the retry: attempt 2 starts unloaded
    samples = pd.read_json(out / "samples.jsonl", lines=True)
    assert set(samples.attempt) == {1, 2}


def test_wrong_load_twice_gives_a_failed_row_not_a_bad_number(small_plan, tmp_path):
    out = tmp_path / "run"
    half = lambda c: c.call("apply_load", wrench=[1100, 0, 1100, 100, -100, 0],  # noqa: E731
                            name="wrong")
    rep = Injector([("load_applied", 1, None, half)])
    outcome = _run(small_plan, out, rep)
    assert outcome.status == "complete"
    tests = pd.read_csv(out / "tests.csv", keep_default_na=False)
    row = tests[tests.test_id == 1].iloc[0]
    assert row.status == "failed"
    assert row["flags"].split(";") == ["wrench_mismatch", "retried"]
    plan = pd.read_csv(small_plan / "plan.csv").set_index("test")
    f_plan = plan.loc[1, ["fx_N", "fy_N", "fz_N"]].to_numpy(dtype=float)
    expected = np.linalg.norm(np.array([1100, 0, 1100]) - f_plan)  # N, > 1500 N
    assert abs(row.wrench_error_N - expected) < 10
    assert np.allclose([row.fx_N, row.fy_N, row.fz_N], [1100, 0, 1100], atol=10)
    assert list(tests.status[1:]) == ["ok", "ok"]
    assert sum(e["event"] == "retry" for e in rep.events) == 1


def test_dead_sensor_aborts_with_earlier_data_intact_then_resume(small_plan, tmp_path):
    out = tmp_path / "run"
    rep = Injector([("test_done", 1, None,
                     lambda c: c.call("fault", device="ati-netft", fault="disconnect",
                                      count=1))])
    outcome = _run(small_plan, out, rep)
    assert outcome.status == "failed"
    assert "device fault after a retry" in outcome.reason
    meta = json.loads((out / "metadata.json").read_text())
    assert meta["status"] == "failed" and meta["reason"] == outcome.reason
    tests = pd.read_csv(out / "tests.csv")
    assert list(tests.test_id) == [1] and tests.status[0] == "ok"
    assert (out / "tests.parquet").is_file()
    first = tests.iloc[0].copy()
    # a fresh lab (the sensor works again): resume finishes the run, test 1 untouched
    outcome = _run(small_plan, out, QuietReporter(), resume=out)
    assert outcome.status == "complete"
    tests = pd.read_csv(out / "tests.csv")
    assert list(tests.test_id) == [1, 2, 3]
    assert np.isclose(tests.iloc[0].dx_mm, first.dx_mm)


def test_force_above_the_limit_stops_and_unloads(small_plan, tmp_path):
    out = tmp_path / "run"
    state = {}

    def overload(c):
        c.call("apply_load", wrench=[0, 3000, 3000, 0, 0, 0], name="too much")

    rep = Injector([("load_applied", 2, None, overload)])
    orig_finish = rep.finish

    def finish(*args):
        state["load"] = rep.client.call("state")["load"]
        orig_finish(*args)

    rep.finish = finish
    outcome = _run(small_plan, out, rep)
    assert outcome.status == "aborted"
    assert "safety stop" in outcome.reason and "4242" in outcome.reason
    assert state["load"] == [0, 0, 0, 0, 0, 0]  # the load was removed
    assert len(pd.read_csv(out / "tests.csv")) == 1
    assert any(e["event"] == "load_removed" for e in rep.events[-3:])
