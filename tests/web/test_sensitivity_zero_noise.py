"""A weighted fit at zero measurement noise has no weights: refused (422), never a 500."""

from __future__ import annotations


def test_zero_noise_weighted_fit_is_refused(client):
    body = {"poses": "zones", "method": "wls", "translation_sigma_um": 0.0,
            "rotation_sigma_urad": 0.0, "force_sigma_N": 0.0, "trials": 5, "n_tests": 4}
    r = client.post("/api/sensitivity", json=body)
    assert r.status_code == 422, r.text
    assert r.json()["detail"].startswith("method: wls weights each test by the inverse of "
                                         "its noise covariance, which is singular")
    ok = client.post("/api/sensitivity", json={**body, "method": "ols"})
    assert ok.status_code == 200, ok.text  # the unweighted fit needs no weights
