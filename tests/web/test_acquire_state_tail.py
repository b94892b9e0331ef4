"""GET /api/acquire/state reads the events file incrementally, with a full reading's answer.

On 10,000 events (1.6 MB; ``python benchmarks/bench_acquire_state.py`` on the 2-core
development machine, shared): a full reading per poll took 35 ms of CPU (145 ms wall
under load), the incremental reading after one appended line 0.13 ms (its JSON line:
``full_cpu_ms_per_poll`` 34.6, ``incremental_cpu_ms_per_poll`` 0.126).
"""

from __future__ import annotations

import io
import json
import os
import random

import pytest

from campaign.acquire.progress import JsonReporter
from campaign.web.acquire_api import LIVE, _record_path
from campaign.web.events_tail import EventsTail, summarize

pytest.importorskip("fastapi", reason="fastapi is not installed (pip install fastapi)")
N_EVENTS = 10_000


def events_text(n: int, seed: int = 0, finish: bool = True) -> str:
    """A campaign's events as ``campaign acquire --json`` writes them: start, phases of
    tests (with messages and other events between), finish."""
    rng = random.Random(seed)
    out = io.StringIO()
    rep = JsonReporter(out)
    rep.start({"total": n // 10, "robot": "kr240-2", "run_dir": "runs/r"})
    phases = ["approach", "settle_unloaded_before", "tare", "apply_load", "settle_loaded",
              "loaded", "remove_load", "unloaded_after"]
    for i in range(n):
        if i % 97 == 0:
            rep.message(f"note {i}")
        elif i % 101 == 0:
            rep.event({"event": "test_done", "test_id": i // 10, "status": "ok"})
        else:
            state = {"phase": phases[i % len(phases)], "test_id": i // 10 + 1,
                     "repeat": i % 3 + 1, "done": i // 10, "total": n // 10}
            if i % 8 == 5:
                state["wrench"] = [rng.uniform(-2000, 2000) for _ in range(6)]
                state["deflection_mm"] = rng.uniform(0, 2)
            rep.phase(**state)
    if finish:
        rep.finish("complete", "", {"ok": n // 10, "failed": 0})
    return out.getvalue()


def test_tail_equals_a_full_reading_at_every_cut(tmp_path):
    """The file written in random pieces (cut mid-line too): after each, the tail's answer
    is the full reading's; then a replaced file and a truncated one."""
    text = events_text(N_EVENTS).encode()
    path = tmp_path / "events.jsonl"
    path.write_bytes(b"")
    tail = EventsTail(path, LIVE)
    rng = random.Random(1)
    pos = checks = 0
    while pos < len(text):
        step = rng.choice([1, 7, 50, 400, 5000, 60000, 200000])
        with open(path, "ab") as f:
            f.write(text[pos:pos + step])
        pos += step
        got, full = tail.read(), summarize(path, LIVE)
        assert got == full
        checks += 1
    assert checks > 20 and tail.offset == len(text)
    final = tail.read()
    assert final.finish["status"] == "complete" and final.start["total"] == N_EVENTS // 10
    assert final.live["test_id"] == N_EVENTS // 10 and "wrench" in final.live
    # a file replaced by another (new inode), then one cut shorter: read again from the start
    other = tmp_path / "other.jsonl"
    other.write_text(events_text(300, seed=5, finish=False))
    os.replace(other, path)
    assert tail.read() == summarize(path, LIVE) and tail.read().finish is None
    path.write_bytes(path.read_bytes()[:1000])
    assert tail.read() == summarize(path, LIVE)
    path.unlink()
    assert tail.read() == summarize(path, LIVE)


def _app(ws):
    from fastapi import FastAPI
    from fastapi.testclient import TestClient

    from campaign.web import acquire_api

    app = FastAPI()
    app.state.workspace = ws
    app.include_router(acquire_api.router)
    return TestClient(app)


def test_state_answers_as_a_fresh_server_reading_everything(tmp_path):
    ws = tmp_path / "ws"
    (ws / "runs" / "r").mkdir(parents=True)
    (ws / "runs" / "r" / "metadata.json").write_text(json.dumps({"status": "running"}))
    jobs = ws / ".gui" / "acquire"
    jobs.mkdir(parents=True)
    events = jobs / "runs%2Fr.1.events.jsonl"
    events.write_text("")
    _record_path(ws, ws / "runs" / "r").write_text(json.dumps({
        "run_dir": "runs/r", "pid": None, "events_file": str(events.relative_to(ws)),
        "log": ".gui/acquire/runs%2Fr.1.log"}))
    (jobs / "latest").write_text("runs/r")
    text = events_text(N_EVENTS).encode()
    polling = _app(ws)
    for cut in (0, 333, len(text) // 2 + 17, len(text) - 5, len(text)):
        events.write_bytes(text[:cut])
        got = polling.get("/api/acquire/state").json()
        assert got == _app(ws).get("/api/acquire/state").json()  # a server with no tail
    assert got["finish"]["status"] == "complete" and got["total"] == N_EVENTS // 10
    # the last phase line is event 9998 (9999 is another event): remove_load
    assert got["live"]["phase"] == "remove_load" and got["stage"] == "unload"
