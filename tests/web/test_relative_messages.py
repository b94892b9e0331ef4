"""A job's refusal names a file as the client gave it, relative to the workspace, not by
the server's absolute path (the sensitivity explorer's missing plan said
'/tmp/.../ws/nosuch: the plan directory does not exist')."""

from __future__ import annotations


def test_missing_plan_is_named_relative_to_the_workspace(client, workspace):
    r = client.post("/api/sensitivity", json={"poses": "plan", "plan": "nosuch", "trials": 2})
    assert r.status_code == 422
    d = r.json()
    assert str(workspace) not in d["detail"] and str(workspace) not in str(d["where"])
    assert d["detail"].startswith("nosuch: the plan directory does not exist"), d
