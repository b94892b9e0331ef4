"""A request the API's models refuse is answered with sentences that name the field and what
it accepts (the page shows them as they are), not pydantic's wording."""

from __future__ import annotations

import pytest

from campaign.web.sensitivity_api import API_MAX_TRIALS


@pytest.mark.parametrize("body,detail,field", [
    ({"trials": API_MAX_TRIALS + 4000}, f"trials: at most {API_MAX_TRIALS} (got 9000)", "trials"),
    ({"trials": 1}, "trials: at least 2 (got 1)", "trials"),
    ({"method": "lsq"}, "method: one of 'ols', 'wls' or 'exact' (got 'lsq')", "method"),
    ({"n_tests": "ten"}, "n_tests: a whole number (got 'ten')", "n_tests"),
    ({"q_deg": [[0, "a"]]}, "q_deg[0][1]: a number (got 'a')", "q_deg[0][1]"),
])
def test_a_refused_field_is_named_with_its_bound(client, body, detail, field):
    r = client.post("/api/sensitivity", json=body)
    assert r.status_code == 422, r.text
    assert r.json() == {"detail": detail, "field": field}


def test_every_refused_field_is_one_sentence(client):
    r = client.post("/api/jobs/analyze", json={"method": "x", "trials": "y"})
    assert r.status_code == 422
    d = r.json()
    assert d["detail"] == ("method: one of 'ols', 'wls' or 'exact' (got 'x'); "
                           "trials: a whole number (got 'y')")
    assert "Input should" not in d["detail"] and "body." not in d["detail"]
