"""A page left open across a restart of the GUI server holds the old token: every request
is refused (403) with a line that says what to do, and the acquisition view of a new
page (the new URL) reattaches to the run from its files."""

from __future__ import annotations

from fastapi.testclient import TestClient


def test_old_token_after_a_restart_says_open_the_new_url(workspace):
    from campaign.web.app import create_app

    old = TestClient(create_app(workspace, "token-before-restart-0123"))
    assert old.get("/?token=token-before-restart-0123").status_code == 200
    # the server restarts with a new token; the browser still sends the old cookie
    new_app = create_app(workspace, "token-after-restart-4567")
    stale = TestClient(new_app, cookies=dict(old.cookies))
    r = stale.get("/api/acquire/state")
    assert r.status_code == 403
    assert "restarted" in r.json()["detail"] and "campaign gui" in r.json()["detail"]
    fresh = TestClient(new_app)
    assert fresh.get("/?token=token-after-restart-4567").status_code == 200
    assert fresh.get("/api/session").status_code == 200
