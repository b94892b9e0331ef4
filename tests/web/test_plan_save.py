"""A refused Plan form changes no protocol file: "Save the protocol only" and "Save and
plan" with a value the protocol reader refuses leave neither an unreadable
``protocols/NAME.toml`` nor a good one of that name overwritten."""

from __future__ import annotations

import pytest

from tests.web.conftest import post_followed


@pytest.mark.parametrize("route", ["/api/plan/save", "/api/plan/run"])
def test_a_refused_form_keeps_the_protocol_file(client, workspace, route):
    ok = client.post("/api/plan/save", json={"values": {"campaign.tests": "4"}, "name": "p"})
    assert ok.status_code == 200, ok.text
    saved = workspace / "protocols" / "p.toml"
    good = saved.read_bytes()
    assert b"tests = 4" in good
    bad = post_followed(client, route, json={"values": {"campaign.tests": "-3"}, "name": "p",
                                   "candidates": 100})
    assert bad.status_code == 400
    d = bad.json()
    assert d["field"] == "campaign.tests"
    assert d["detail"].startswith("protocols/p.toml:") and "(got -3)" in d["detail"]
    assert saved.read_bytes() == good
    new = post_followed(client, route, json={"values": {"campaign.tests": "-3"}, "name": "q",
                                   "candidates": 100})
    assert new.status_code == 400 and new.json()["field"] == "campaign.tests"
    assert not (workspace / "protocols" / "q.toml").exists()
    assert not (workspace / "plans" / "q").exists()


def test_an_existing_name_is_refused_unless_replacing_is_asked(client, workspace):
    """"Save and plan" and "Save the protocol only" under a name already used leave
    protocols/NAME.toml and plans/NAME as they were (the command line refuses a non-empty
    --out without --force); with ``force`` (the page's "Replace a protocol and plan of this
    name") they are replaced."""
    first = post_followed(client, "/api/plan/run", json={"values": {"campaign.tests": "4"},
                                               "name": "p", "candidates": 100})
    assert first.status_code == 200, first.text
    proto, plan_csv = workspace / "protocols" / "p.toml", workspace / "plans" / "p" / "plan.csv"
    before = proto.read_bytes(), plan_csv.read_bytes()
    for route in ("/api/plan/run", "/api/plan/save"):
        again = post_followed(client, route, json={"values": {"campaign.tests": "6"}, "name": "p",
                                         "candidates": 100})
        assert again.status_code == 400, again.text
        d = again.json()
        assert d["field"] == "name" and d["options"] == {"--force": "force"}
        assert "protocols/p.toml" in d["detail"] and "already exist" in d["detail"]
        assert (proto.read_bytes(), plan_csv.read_bytes()) == before
    assert "plans/p" in post_followed(client, "/api/plan/run", json={
        "values": {"campaign.tests": "6"}, "name": "p", "candidates": 100}).json()["detail"]
    replaced = post_followed(client, "/api/plan/run", json={"values": {"campaign.tests": "6"},
                                                  "name": "p", "candidates": 100,
                                                  "force": True})
    assert replaced.status_code == 200, replaced.text
    assert b"tests = 6" in proto.read_bytes() and plan_csv.read_bytes() != before[1]
    assert len(replaced.json()["rows"]) == 6
