"""A refused Plan form changes no protocol file: "Save the protocol only" and "Save and
plan" with a value the protocol reader refuses leave neither an unreadable
``protocols/NAME.toml`` nor a good one of that name overwritten."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("route", ["/api/plan/save", "/api/plan/run"])
def test_a_refused_form_keeps_the_protocol_file(client, workspace, route):
    ok = client.post("/api/plan/save", json={"values": {"campaign.tests": "4"}, "name": "p"})
    assert ok.status_code == 200, ok.text
    saved = workspace / "protocols" / "p.toml"
    good = saved.read_bytes()
    assert b"tests = 4" in good
    bad = client.post(route, json={"values": {"campaign.tests": "-3"}, "name": "p",
                                   "candidates": 100})
    assert bad.status_code == 400
    d = bad.json()
    assert d["field"] == "campaign.tests"
    assert d["detail"].startswith("protocols/p.toml:") and "(got -3)" in d["detail"]
    assert saved.read_bytes() == good
    new = client.post(route, json={"values": {"campaign.tests": "-3"}, "name": "q",
                                   "candidates": 100})
    assert new.status_code == 400 and new.json()["field"] == "campaign.tests"
    assert not (workspace / "protocols" / "q.toml").exists()
    assert not (workspace / "plans" / "q").exists()
