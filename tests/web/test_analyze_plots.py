"""The Analyze part's residual and validation plots (``GET /api/analyze/plots``): the
numbers the analyze job wrote, unchanged (residuals.csv row for row, results.json's
threshold and held-out validation); and the page after an analysis and a re-analysis
with another method, whose plots carry exactly those numbers."""

from __future__ import annotations

import csv
import json
import math
import shutil
from pathlib import Path

import pytest

from tests.web.conftest import copy_acquired

pytestmark = pytest.mark.timeout(150)


@pytest.fixture(scope="module")
def analysed(tmp_path_factory, acquired_kr240) -> Path:
    """A workspace with a run of 6 KR240-2 tests on the simulated lab, analysed (ols)."""
    import pandas as pd

    from campaign.jobs.analyze import AnalyzeOptions
    from campaign.jobs.analyze import run as analyze
    from campaign.jobs.choices import Method

    ws = copy_acquired(acquired_kr240, tmp_path_factory.mktemp("plots-ws"))
    # run2: the same tests with a gross error (dz of the 5th test +0.5 mm), accepted
    shutil.copytree(ws / "run", ws / "run2", ignore=shutil.ignore_patterns("*.parquet"))
    tests = pd.read_csv(ws / "run2" / "tests.csv")
    tests.loc[4, "dz_mm"] += 0.5
    tests.to_csv(ws / "run2" / "tests.csv", index=False)
    for run, accept in (("run", False), ("run2", True)):
        analyze(AnalyzeOptions(run_dir=ws / run, method=Method("ols"), report=False,
                               accept_misfit=accept))
    return ws


@pytest.fixture
def workspace(analysed) -> Path:
    return analysed


def _residuals_csv(ws: Path, run: str = "run") -> list[dict]:
    with open(ws / run / "analysis" / "residuals.csv", newline="") as f:
        return list(csv.DictReader(f))


def _results(ws: Path, run: str = "run") -> dict:
    return json.loads((ws / run / "analysis" / "results.json").read_text())


def test_plots_are_the_analysis_files(client, analysed):
    r = client.get("/api/analyze/plots", params={"run_dir": "run"})
    assert r.status_code == 200, r.text
    d = r.json()
    rows, res = _residuals_csv(analysed), _results(analysed)
    assert d["residual_rows"] == len(rows) == 36 and d["residuals_shown"] == "all 36 rows"
    assert d["residuals"]["studentized"] == [float(x["studentized"]) for x in rows]
    assert d["residuals"]["residual"] == [float(x["residual"]) for x in rows]
    assert d["residuals"]["outlier"] == [x["outlier"] == "True" for x in rows]
    assert d["residuals"]["component"] == [x["component"] for x in rows]
    # results.json lists the same residuals (all of them at this size)
    assert [x["studentized"] for x in res["residuals"]] == pytest.approx(
        d["residuals"]["studentized"], rel=1e-12)
    assert d["threshold"] == res["outlier_threshold_studentized"] > 3
    assert d["method"] == res["method"] == "ols"
    val = res["validation"]
    assert len(d["validation"]) == len(val) == res["validation_summary"]["n_poses"]
    for got, want in zip(d["validation"], val, strict=True):
        for k in ("rms_normalized", "rms_normalized_total", "limit_normalized_total",
                  "p_value_total", "beyond_limit", "n_tests"):
            assert got[k] == want[k], k
        assert got["held_out_pose"] == str(want["held_out_pose"])
    assert d["validation_limit"] == res["validation_summary"]["limit"]
    # the run with a gross error: its outlier and the poses beyond the limit, as written
    d = client.get("/api/analyze/plots", params={"run_dir": "run2"}).json()
    res, rows = _results(analysed, "run2"), _residuals_csv(analysed, "run2")
    flagged = [i for i, x in enumerate(rows) if x["outlier"] == "True"]
    assert flagged and [i for i, v in enumerate(d["residuals"]["outlier"]) if v] == flagged
    assert all(rows[i]["component"] == "dz" for i in flagged)
    beyond = [v["held_out_pose"] for v in d["validation"] if v["beyond_limit"]]
    assert beyond and beyond == [str(p) for p in res["validation_summary"]
                                 ["poses_beyond_limit"]]


def test_plots_refusals(client, analysed, tmp_path, monkeypatch):
    assert client.get("/api/analyze/plots", params={"run_dir": "../x"}).status_code == 400
    assert client.get("/api/analyze/plots", params={"run_dir": "plan"}).status_code == 404
    assert client.get("/api/analyze/plots").status_code == 422
    # above MAX_POINTS rows: results.json's listed rows, said so
    from campaign.web import analyze_plots_api

    monkeypatch.setattr(analyze_plots_api, "MAX_POINTS", 10)
    d = client.get("/api/analyze/plots", params={"run_dir": "run"}).json()
    assert d["residual_rows"] == 36 and len(d["residuals"]["studentized"]) == 36
    assert d["residuals_shown"] == "all 36 rows"


def test_residual_table_reads_empty_cells_as_missing():
    from campaign.web.analyze_plots_api import residual_table

    t = residual_table([{"test": "3", "pose": "2", "component": "dx", "unit": "m",
                         "residual": "1e-05", "sigma": "", "studentized": "nan",
                         "outlier": "False", "set_aside": "True"}])
    assert t["test"] == [3.0] and t["residual"] == [1e-05] and t["sigma"] == [None]
    assert t["studentized"] == [None] and t["outlier"] == [False] and t["set_aside"] == [True]
    assert t["weight"] == [None]  # a Gaussian fit's table has no weight column


def _plotted(page) -> dict:
    return page.evaluate("""() => { const s = window.anPlots.state;
        const res = s.res.data, val = s.val.data;
        const pts = res.slice(1, res.length - 4).flatMap((c) => c.filter((v) => v !== null));
        return { residuals: pts.length, resMax: Math.max(...pts.map(Math.abs)),
                 threshold: res[res.length - 2][0], outliers: res[res.length - 4]
                   .filter((v) => v !== null).length,
                 total: val[1], limit: val[2], noise: val[3],
                 beyond: val[4].filter((v) => v !== null).length,
                 maxText: document.getElementById('an-res-max').textContent,
                 resPoints: document.getElementById('an-res-fig').dataset.points }; }""")


def test_page_plots_after_an_analysis_and_a_reanalysis(server, analysed, open_url):
    page = open_url(server)
    page.wait_for_function("() => document.body.dataset.planview === 'ready'",
                           timeout=30_000)
    page.click("#tab-plan")
    page.select_option("#an-run", "run")  # analysed already (ols): its plots shown
    page.wait_for_function("() => document.getElementById('an-plots').dataset.ready")
    _check(page, analysed, "ols")
    page.select_option("#an-method", "wls")
    page.check("#an-force")
    page.evaluate("() => { document.getElementById('an-plots').dataset.ready = ''; }")
    page.click("#an-run-btn")
    page.wait_for_function("() => document.body.dataset.analyze === 'done'",
                           timeout=90_000)
    page.wait_for_function("() => document.getElementById('an-plots').dataset.ready")
    _check(page, analysed, "wls")
    page.select_option("#an-run", "run2")  # the run with a gross error (accepted)
    page.wait_for_function("() => document.getElementById('an-plots').dataset.run"
                           " === 'run2'")
    got = _check(page, analysed, "ols", "run2")
    assert got["outliers"] >= 1 and got["beyond"] >= 1
    assert page.locator("#an-val-fig").get_attribute("data-beyond") == ",".join(
        str(p) for p in _results(analysed, "run2")["validation_summary"]
        ["poses_beyond_limit"])
    page.select_option("#an-run", "run")
    page.wait_for_function("() => document.getElementById('an-plots').dataset.run"
                           " === 'run'")
    # hover: the row under the cursor, its values as in residuals.csv
    page.locator("#an-res-fig .u-over").hover(position={"x": 5, "y": 100})
    info = page.locator("#an-res-info").text_content()
    first = _residuals_csv(analysed)[0]
    test = int(float(first["test"]))
    assert info.startswith(f"row 1: test {test}, pose {first['pose']}, "
                           f"{first['component']}: studentized "
                           f"{float(first['studentized']):.3f}"), info


def _check(page, ws: Path, method: str, run: str = "run") -> dict:
    res, rows = _results(ws, run), _residuals_csv(ws, run)
    assert res["method"] == method
    got = _plotted(page)
    t = [x["studentized"] for x in res["residuals"]]
    assert got["residuals"] == len(rows) == len(t) == int(got["resPoints"])
    worst = max(abs(v) for v in t)
    assert got["resMax"] == pytest.approx(worst, rel=1e-12)
    assert got["maxText"].startswith(f"largest |studentized residual| {worst:.3f} ")
    assert got["threshold"] == res["outlier_threshold_studentized"]
    assert got["outliers"] == sum(x["outlier"] for x in res["residuals"])
    val = res["validation"]
    assert got["total"] == [v["rms_normalized_total"] for v in val]
    assert got["limit"] == [v["limit_normalized_total"] for v in val]
    assert got["noise"] == [v["rms_normalized"] for v in val]
    assert got["beyond"] == sum(bool(v["beyond_limit"]) for v in val)
    assert all(math.isfinite(x) for x in got["total"])
    return got
