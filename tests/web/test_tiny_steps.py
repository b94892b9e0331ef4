"""A grid step so small that the number of map points overflows a float is refused with
the server's bound (400 naming step_rad), never a 500 (found by the OpenAPI fuzz)."""

from __future__ import annotations

import math

import pytest


@pytest.mark.parametrize("step", [7.04035032536829e-192, 5e-324, 1e-160])
def test_maps_refuses_a_step_whose_grid_overflows(client, step):
    r = client.post("/api/jobs/maps", json={"robot": "kr240-2", "out": "maps", "step_rad": step})
    assert r.status_code == 400, r.text
    d = r.json()
    assert d["field"] == "step_rad" and "above this server's limit" in d["detail"]


def test_map_points_counts_the_grid():
    from campaign.web.api_jobs import map_points

    assert map_points(math.pi) == 9.0  # 3 points a turn per axis: -pi, 0, pi
    assert map_points(1e-300) == math.inf
    assert map_points(0.0) is None and map_points(-1.0) is None
