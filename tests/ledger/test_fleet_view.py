"""The GUI's Fleet view in a real headless Chromium (Debian's ``chromium``, Playwright).

A workspace holds four demo campaigns of robot KR-0001 (the fourth with k2 10 %
lower) recorded in an SQLite ledger; the GUI is started with that ledger. The page
must list the robot with its alarm on joint 2, and its campaigns with the numbers of
each results.json (kN m/rad, 1 decimal), the alarm cell marked, a working link to
each campaign's files; and the API's answer must be the jobs' own.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from campaign.cli.app import main
from tests.ledger.conftest import SERIAL
from tests.web.conftest import browser_page, gui_server

#: the session's four demo campaigns are made in the first test's setup (minutes on a
#: loaded machine): beyond the suite's 300 s default
pytestmark = pytest.mark.timeout(1200)

TOKEN = "fleet-token-0123456789"


def k_text(k: float, ci: list[float]) -> str:
    return f"{k / 1e3:.1f} [{ci[0] / 1e3:.1f}, {ci[1] / 1e3:.1f}]"


def test_the_fleet_view_shows_the_alarm_and_the_trend(browser, demo_runs, tmp_path,
                                                      monkeypatch):
    monkeypatch.delenv("STIFFNESS_CAMPAIGN_DB", raising=False)
    ws = tmp_path / "ws"
    for i, run in enumerate(demo_runs, start=1):
        shutil.copytree(run, ws / f"c{i}" / "run")
    db = tmp_path / "fleet.sqlite"
    runs = [ws / f"c{i}" / "run" for i in range(1, 5)]
    assert main(["history", "add", *map(str, runs), "--db", str(db)]) == 0
    monkeypatch.setenv("STIFFNESS_CAMPAIGN_DB", str(db))  # the GUI's ledger, as configured
    results = [json.loads((r / "analysis" / "results.json").read_text()) for r in runs]
    with gui_server(ws, TOKEN) as url, browser_page(browser, url) as page:
        page.wait_for_selector("#tab-fleet")
        page.click("#tab-fleet")
        row = page.locator(f'#fleet-robots tr[data-robot="{SERIAL}"]')
        row.wait_for(timeout=30_000)
        cells = row.locator("td").all_inner_texts()
        assert cells[0] == SERIAL and cells[2] == "4"
        assert cells[4] == "alarm" and cells[5] == "2"
        assert results[3]["report_id"] in cells[3]
        row.locator("button.fleet-open").click()
        page.wait_for_selector("#fleet-trend:not([hidden]) tbody tr")
        rows = page.locator("#fleet-trend tbody tr")
        assert rows.count() == 4
        for i, res in enumerate(results):
            r = rows.nth(i)
            assert r.get_attribute("data-report") == res["report_id"]
            shown = [r.locator(f"td.k{j}").inner_text() for j in range(1, 7)]
            assert shown == [k_text(k, ci) for k, ci in zip(
                res["joint_stiffness_Nm_per_rad"], res["ci95_Nm_per_rad"], strict=True)]
        marked = page.locator("#fleet-trend td.alarm")
        assert marked.count() == 1
        assert marked.get_attribute("class") == "k2 alarm"
        assert "ALARM joint 2" in page.locator("#fleet-alarms").inner_text()
        # each campaign's link opens its files through the server (inside the workspace)
        href = rows.nth(3).locator("a").get_attribute("href")
        assert href == "/api/runs/file?path=c4%2Frun%2Fanalysis%2Fresults.json"
        got = page.evaluate(f"async () => (await fetch({json.dumps(href)})).json()")
        assert got["report_id"] == results[3]["report_id"]
        api = page.evaluate("async () => (await fetch('/api/fleet/robot?robot=" + SERIAL
                            + "')).json()")
    from campaign.jobs.history import robot_view

    want = robot_view(str(db), SERIAL)
    assert api["alarms"] == json.loads(json.dumps(want["alarms"]))
    assert [c["k_Nm_per_rad"] for c in api["campaigns"]] == [
        r["joint_stiffness_Nm_per_rad"] for r in results]


def test_without_a_ledger_the_view_says_how_to_configure_one(browser, tmp_path, monkeypatch):
    monkeypatch.delenv("STIFFNESS_CAMPAIGN_DB", raising=False)
    ws = tmp_path / "ws"
    ws.mkdir()
    with gui_server(ws, TOKEN) as url, browser_page(browser, url) as page:
        page.wait_for_selector("#tab-fleet")
        page.click("#tab-fleet")
        page.locator("#fleet-error", has_text="--db").wait_for(timeout=30_000)
        assert "STIFFNESS_CAMPAIGN_DB" in page.locator("#fleet-error").inner_text()
        assert page.locator("#fleet-robots tbody tr").count() == 0
    assert sorted(Path(ws).iterdir()) == []
