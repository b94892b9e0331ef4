"""The Acquire view's zone map and live test (``/api/acquire/map``, ``/poses``, ``/trace``):
the candidates drawn again equal the planner's own, a pose is done exactly when every
(test, repeat) of it is in tests.csv, the live trace follows the events file; and a
browser run on the simulated lab whose map marks exactly the finished poses, during the
run, after a reload and at the end."""

from __future__ import annotations

import csv
import json
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.timeout(120)
PROTOCOL = Path(__file__).parents[2] / "protocols" / "kr240-2.toml"
#: the simulated lab's clock runs this much faster than the wall clock
FAST = 200.0


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """(the Plan of the KR240-2 protocol, 400 candidates; its directory cut to 3 tests of
    2 repeats)."""
    import pandas as pd

    from campaign.planning.planner import make_plan, write_plan
    from campaign.protocol import load_protocol

    plan = make_plan(load_protocol(PROTOCOL), candidates=400, seed=3)
    out = tmp_path_factory.mktemp("map-plan") / "plan"
    write_plan(plan, out, figure=False)
    df = pd.read_csv(out / "plan.csv", dtype={"zone": str, "load_case": str, "method": str})
    df.iloc[:3].assign(repeats=2).to_csv(out / "plan.csv", index=False)
    return plan, out


@pytest.fixture
def workspace(tmp_path, planned) -> Path:
    ws = tmp_path / "ws"
    ws.mkdir()
    shutil.copytree(planned[1], ws / "plan")
    return ws


def test_map_candidates_are_the_planners(client, workspace, planned):
    plan, _ = planned
    r = client.get("/api/acquire/map", params={"plan": "plan"})
    assert r.status_code == 200, r.text
    d = r.json()
    ok = np.any(plan.candidates.valid, axis=1)
    want = np.degrees(plan.candidates.q[ok])
    got = np.array(d["candidates"]["q_deg"]).T
    assert d["candidates"]["count"] == int(ok.sum()) == d["poses_passing"] and d["note"] == ""
    assert d["candidates"]["drawn"] == 400 and got.shape == want.shape
    np.testing.assert_allclose(got, want, atol=5e-4)
    summary = json.loads((workspace / "plan" / "summary.json").read_text())
    assert d["candidates"]["count"] == summary["candidates"]["poses_passing"]
    # the chosen poses: plan.csv's first 3 tests, each one of those candidates
    rows = list(csv.DictReader(open(workspace / "plan" / "plan.csv")))
    assert [c["pose"] for c in d["chosen"]] == sorted({r["pose"] for r in rows}, key=int)
    for c in d["chosen"]:
        mine = [r for r in rows if r["pose"] == c["pose"]]
        assert c["tests"] == [int(r["test"]) for r in mine]
        assert c["q_deg"] == pytest.approx([float(mine[0][f"q{j}_model_deg"])
                                            for j in range(1, 7)], abs=1e-9)
        np.testing.assert_allclose(got[c["candidate"]], c["q_deg"], atol=6e-4)
    # zones: the planner's boxes over (theta2, theta3), in deg
    np.testing.assert_allclose([(z["lo_deg"][1], z["hi_deg"][2]) for z in d["zones"]],
                               [(np.degrees(b.lo[1]), np.degrees(b.hi[2])) for b in plan.boxes])
    assert d["axes"] == [2, 3]
    # the background: the Plan view's 1/kappa_F grid of the same plan (made from the plan
    # in memory), at the protocol's fixed joints
    from campaign.planning.map_data import map_points

    theirs = map_points(plan, size=len(d["grid"]["theta2_deg"]))["grid"]
    np.testing.assert_allclose(d["grid"]["inv_kappa"], theirs["inv_kappa"], atol=1e-6)
    np.testing.assert_allclose(d["grid"]["theta3_deg"], theirs["theta3_deg"], atol=1e-9)
    assert 0 < np.max(d["grid"]["inv_kappa"]) <= 1
    assert "fixed_deg" in d["grid"]["rule_text"]


def test_map_of_an_edited_plan_says_its_poses_are_not_candidates(client, workspace):
    import pandas as pd

    df = pd.read_csv(workspace / "plan" / "plan.csv")
    df.loc[0, "q2_model_deg"] += 0.01  # 0.01 deg off its candidate
    df.to_csv(workspace / "plan" / "plan.csv", index=False)
    d = client.get("/api/acquire/map", params={"plan": "plan"}).json()
    assert "not among the candidates" in d["note"]
    first = next(c for c in d["chosen"] if c["tests"] == [int(df.loc[0, "test"])])
    assert first["candidate"] is None and first["q_deg"][1] == pytest.approx(
        df.loc[0, "q2_model_deg"])
    assert all(c["candidate"] is not None for c in d["chosen"] if c is not first)


def test_map_without_summary_and_refusals(client, workspace):
    (workspace / "plan" / "summary.json").unlink()
    d = client.get("/api/acquire/map", params={"plan": "plan"}).json()
    assert d["candidates"]["count"] == 0 and "summary.json" in d["note"]
    assert len(d["chosen"]) == 3
    assert client.get("/api/acquire/map", params={"plan": "../x"}).status_code == 400
    assert client.get("/api/acquire/map", params={"plan": "nope"}).status_code == 404
    assert client.get("/api/acquire/map", params={"run": "a", "plan": "b"}).status_code == 400
    assert client.get("/api/acquire/map").status_code == 404  # no run started
    assert client.get("/api/acquire/poses", params={"run": "plan/../x"}).status_code == 400
    (workspace / "plan" / "plan.csv").write_text("test,pose\n1,\n")
    r = client.get("/api/acquire/map", params={"plan": "plan"})
    assert r.status_code == 400 and "plan.csv" in r.json()["detail"], r.text


def test_pose_progress_counts_every_test_and_repeat():
    from campaign.web.acquire_map_api import pose_progress

    plan = [{"test": 1, "pose": "1", "repeats": 2}, {"test": 2, "pose": "1", "repeats": 2},
            {"test": 3, "pose": "2", "repeats": 1}, {"test": 4, "pose": "3", "repeats": 1}]
    rows = [{"test_id": "1", "repeat": "1", "status": "ok"},
            {"test_id": "1", "repeat": "2", "status": "ok"},
            {"test_id": "2", "repeat": "1", "status": "ok"},
            {"test_id": "3.0", "repeat": "1", "status": "failed"}]
    got = {p["pose"]: (p["status"], p["rows_done"], p["rows_planned"])
           for p in pose_progress(plan, rows)}
    assert got == {"1": ("partial", 3, 4), "2": ("failed", 1, 1), "3": ("pending", 0, 1)}
    rows.append({"test_id": "2", "repeat": "2", "status": "ok"})
    assert pose_progress(plan, rows)[0]["status"] == "done"
    with pytest.raises(ValueError, match="repeats 1000000000 outside 1..1000"):
        pose_progress([{"test": 1, "pose": "1", "repeats": 10**9}], [])


def test_poses_endpoint_reads_tests_csv_as_written(client, workspace):
    run = workspace / "r"
    run.mkdir()
    shutil.copy(workspace / "plan" / "plan.csv", run / "plan.csv")
    plan = list(csv.DictReader(open(run / "plan.csv")))
    head = "test_id,repeat,status,flags\n"
    t1, t2 = plan[0]["test"], plan[1]["test"]
    # test 1 twice ok, test 2 once failed, and a last line still being written
    (run / "tests.csv").write_text(head + f"{t1},1,ok,\n{t1},2,ok,\n{t2},1,failed,drift\n"
                                   f"{t2},2,o")
    d = client.get("/api/acquire/poses", params={"run": "r"}).json()
    assert d["rows_read"] == 3
    status = {p["pose"]: (p["status"], p["rows_done"], p["rows_failed"]) for p in d["poses"]}
    assert status == {plan[0]["pose"]: ("done", 2, 0), plan[1]["pose"]: ("partial", 1, 1),
                      plan[2]["pose"]: ("pending", 0, 0)}
    assert d["done"] == [plan[0]["pose"]]
    (run / "tests.csv").write_text(head + f"{t1},1,ok,\n{t1},2,ok,\n{t2},1,failed,drift\n"
                                   f"{t2},2,ok,\n")
    d = client.get("/api/acquire/poses", params={"run": "r"}).json()
    assert d["poses"][1]["status"] == "failed" and d["rows_read"] == 4
    assert client.get("/api/acquire/poses", params={"run": "plan2"}).status_code == 404


def test_trace_follows_the_last_test_of_the_events():
    from campaign.web.acquire_map_api import current_trace

    def ph(t, **kw):
        return {"event": "phase", "elapsed_s": t, **kw}

    lines = [ph(0.0, phase="approach", test_id=1, repeat=1, attempt=1, pose="1"),
             ph(0.5, phase="apply_load"), ph(0.6, deflection_mm=[9, 9, 9]),
             ph(0.9, phase="unloaded_after"), ph(1.0, deflection_mm=[1, 2, 3]),
             ph(1.1, phase="approach", test_id=2, repeat=1, attempt=1, pose="2"),
             ph(1.5, phase="apply_load", wrench_planned=[0] * 6), ph(1.6, phase="settle_loaded"),
             ph(1.7, deflection_mm=[0.1, 0.2, 20.0]), ph(1.8, deflection_mm=[0.2, 0.3, 21.0]),
             ph(2.0, phase="loaded"), ph(2.1, wrench=[1, 2, 3, 4, 5, 6])]
    t = current_trace(lines)
    assert (t["test_id"], t["pose"], t["phase"]) == (2, "2", "loaded")
    assert t["t_s"] == pytest.approx([0.2, 0.3])
    assert t["d_mm"] == [[0.1, 0.2], [0.2, 0.3], [20.0, 21.0]]
    assert t["wrench"] == [1, 2, 3, 4, 5, 6] and t["result"] is None
    lines += [ph(2.5, phase="unloaded_after"),
              ph(2.6, deflection_mm=[0.15, 0.25, 20.5], rotation_mrad=[1, 2, 3],
                 wrench=[7, 8, 9, 1, 2, 3])]
    t = current_trace(lines)
    assert t["result"] == {"d_mm": [0.15, 0.25, 20.5], "r_mrad": [1, 2, 3],
                           "wrench": [7, 8, 9, 1, 2, 3]}
    assert len(t["t_s"]) == 2 and t["wrench"] == [1, 2, 3, 4, 5, 6]


def test_trace_tail_read_of_a_long_events_file(tmp_path, monkeypatch):
    from campaign.web import acquire_map_api as m

    monkeypatch.setattr(m, "TAIL", 256)  # the tail is widened until a test opens
    path = tmp_path / "e.jsonl"
    lines = [{"event": "phase", "elapsed_s": 0.0, "phase": "approach", "test_id": 7,
              "repeat": 1, "attempt": 1, "pose": "4"},
             {"event": "phase", "elapsed_s": 1.0, "phase": "apply_load"}]
    lines += [{"event": "phase", "elapsed_s": 1.0 + i, "deflection_mm": [i, 0, 0]}
              for i in range(1, 40)]
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    t = m.current_trace(m._tail_lines(path))
    assert t["test_id"] == 7 and t["d_mm"][0] == list(range(1, 40))
    assert t["t_s"] == pytest.approx(list(range(1, 40)))


def _done_from_file(run_dir: Path, n_rows: int) -> list[str]:
    """The poses all of whose (test, repeat) rows are among tests.csv's first n_rows."""
    plan = list(csv.DictReader(open(run_dir / "plan.csv")))
    rows = list(csv.DictReader(open(run_dir / "tests.csv")))[:n_rows] if (
        run_dir / "tests.csv").exists() else []
    got = {(int(float(r["test_id"])), int(float(r["repeat"]))) for r in rows
           if r["status"] == "ok"}
    done = []
    for pose in sorted({p["pose"] for p in plan}, key=int):
        need = {(int(p["test"]), k) for p in plan if p["pose"] == pose
                for k in range(1, int(p["repeats"]) + 1)}
        if need <= got:
            done.append(pose)
    return done


def _page_map(page) -> dict:
    return page.evaluate("""() => { const m = window.acqMap.state;
        const b = document.getElementById('acq-map');
        const count = (i) => m.plot.data[i].filter((v) => v !== null).length;
        return { done: b.dataset.done ? b.dataset.done.split(',') : [],
                 rows: Number(b.dataset.rows),
                 current: b.dataset.current, candidates: count(1), doneDrawn: count(4),
                 drawn: [2, 3, 4, 5].map(count).reduce((a, c) => a + c, 0),
                 ringed: count(6) }; }""")


def test_browser_map_marks_the_finished_poses(server, workspace, planned, open_url):
    run = workspace / "map-run"
    passing = int(np.any(planned[0].candidates.valid, axis=1).sum())
    page = open_url(server)
    page.click("#tab-acquire")
    page.fill("#acq-plan", "plan")
    page.fill("#acq-out", "map-run")
    page.fill("#acq-scale", str(FAST))
    page.click("#acq-dry")  # the plan's map, before any run
    page.wait_for_function("() => document.getElementById('acq-map').dataset.chosen === '3'")
    assert _page_map(page)["candidates"] == passing
    page.click("#acq-start")
    seen = []
    deadline = time.monotonic() + 60
    reloaded = False
    while time.monotonic() < deadline:
        page.wait_for_function("() => document.getElementById('acq-map').dataset.rows"
                               " !== undefined", timeout=30_000)
        m = _page_map(page)
        status = page.locator("#acq-status").text_content()
        # exactly the poses whose every row is in tests.csv (as far as the page read it)
        assert m["done"] == _done_from_file(run, m["rows"]), m
        assert m["doneDrawn"] == len(m["done"]) and m["drawn"] == 3
        assert m["candidates"] == passing
        if status == "running" and m["current"]:
            assert m["current"] in ("1", "2", "3") and m["ringed"] == 1
        seen.append((m["rows"], tuple(m["done"])))
        if status == "complete" and m["rows"] == 6:
            break
        if not reloaded and 0 < m["rows"] < 6:
            page.reload()  # state from the files: the map comes back as it was
            page.click("#tab-acquire")
            reloaded = True
            page.wait_for_function("() => document.getElementById('acq-map').dataset"
                                   ".rows !== undefined", timeout=30_000)
            again = _page_map(page)
            assert again["done"] == _done_from_file(run, again["rows"])
            assert again["rows"] >= m["rows"]
        time.sleep(0.15)
    assert reloaded and seen[-1] == (6, ("1", "2", "3")), seen
    assert any(0 < rows < 6 for rows, _ in seen)  # the map was seen mid-run
    assert _page_map(page)["current"] == "" and _page_map(page)["ringed"] == 0
    # the finished test's screw beside the trace: the last row of tests.csv (mm, mrad)
    last = list(csv.DictReader(open(run / "tests.csv")))[-1]
    assert page.locator("#acq-trace-d").text_content() == ", ".join(
        f"{float(last[c]):.3f}" for c in ("dx_mm", "dy_mm", "dz_mm"))
    assert page.locator("#acq-trace-r").text_content() == ", ".join(
        f"{float(last[c]):.4f}" for c in ("rx_mrad", "ry_mrad", "rz_mrad"))
    assert int(page.locator("#acq-trace-readings").text_content()) >= 1
    # hover a chosen pose: its number and joint angles (deg), as plan.csv has them
    rows = list(csv.DictReader(open(run / "plan.csv")))
    for r in rows:
        x, y = page.evaluate("""(q) => { const u = window.acqMap.state.plot;
            return [u.valToPos(q[0], 'x'), u.valToPos(q[1], 'y')]; }""",
                             [float(r["q2_model_deg"]), float(r["q3_model_deg"])])
        page.locator("#acq-map .u-over").hover(position={"x": x, "y": y})
        info = page.locator("#acq-map-info").text_content()
        q = ", ".join(f"{float(r[f'q{j}_model_deg']):.3f}" for j in range(1, 7))
        assert info.startswith(f"pose {r['pose']} (") and info.endswith(
            f"done): q1..q6 = {q} deg"), info
