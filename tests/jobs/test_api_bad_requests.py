"""The jobs API answers bad requests with 400 or 422 and one line, never 500, and its
OpenAPI document lists one POST per job."""

from __future__ import annotations

import pytest

JOBS = ("plan", "acquire", "analyze", "stiffness", "maps", "robustness", "compensate",
        "compare", "place", "robots", "demo", "export")
BAD_BODIES = ([], "x", 3, {"robot": 1}, {"robot": "kr240-2", "out": "a\x00b", "q_rad": [0]},
              {"robot": "kr240-2", "out": "x" * 5000, "path": "p.csv", "q_rad": [0]},
              {"plan": "../p", "measurements": "/etc/passwd", "a": "..", "b": ".."})


def test_openapi_lists_one_post_per_job(client):
    doc = client.get("/openapi.json").json()
    posts = [p for p, ops in doc["paths"].items() if "{" not in p]
    assert sorted(p.removeprefix("/api/jobs/") for p in posts) == sorted(JOBS)
    assert all(set(doc["paths"][p]) == {"post"} for p in posts)
    # the queue: a job's state, its events, its cancellation
    assert set(doc["paths"]["/api/jobs/{job_id}"]) == {"get", "delete"}
    assert set(doc["paths"]["/api/jobs/{job_id}/events"]) == {"get"}
    assert set(doc["paths"]["/api/jobs/{job_id}/cancel"]) == {"post"}


@pytest.mark.parametrize("job", JOBS)
@pytest.mark.parametrize("body", BAD_BODIES, ids=range(len(BAD_BODIES)))
def test_bad_bodies_are_refused_not_500(client, ws, job, body):
    answer = client.post(f"/api/jobs/{job}", json=body)  # a queued job: followed to its end
    assert answer.status_code in (200, 400, 409, 422), (answer.status_code, answer.text)
    if answer.status_code == 400:
        assert "\n" not in answer.json()["detail"]
    assert sorted(p.name for p in ws.iterdir()) == []  # nothing written
