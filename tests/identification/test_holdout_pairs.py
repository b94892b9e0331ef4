"""close_pairs: the distance-matrix search of a planned campaign's few poses finds exactly
the pairs of scipy's k-d tree (the search above DENSE_PAIRS_MAX_POSES poses)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from analysis.identification.validation import holdout_check
from analysis.identification.validation.holdout_check import close_pairs


def _pairs(p: np.ndarray) -> set[tuple[int, int]]:
    return {(int(i), int(j)) for i, j in p}


@pytest.mark.parametrize("n_points", [1, 2, 7, 60, holdout_check.DENSE_PAIRS_MAX_POSES])
def test_dense_search_finds_the_k_d_tree_pairs(n_points):
    rng = np.random.default_rng(n_points)
    # clustered joint angles (rad): a few poses nearly repeated, most far apart
    centres = rng.uniform(-2, 2, size=(max(n_points // 3, 1), 6))
    pts = centres[rng.integers(0, len(centres), n_points)] + rng.normal(0, 0.02, (n_points, 6))
    radius = np.radians(5.0)
    dense = close_pairs(pts, radius)
    assert dense.shape[1] == 2 and np.all(dense[:, 0] < dense[:, 1])
    expected = _pairs(cKDTree(pts).query_pairs(radius, output_type="ndarray"))
    assert _pairs(dense) == expected
    if n_points >= 60:
        assert len(expected) > 0  # the case tests pairs, not only their absence


def test_pair_at_the_radius_is_kept_and_just_beyond_is_not():
    pts = np.zeros((3, 6))
    pts[1, 0] = 0.25  # exactly representable: distance 0.25 to point 0
    pts[2, 0] = 0.25 + 0.25 + 1e-9  # just beyond 0.25 from point 1
    assert _pairs(close_pairs(pts, 0.25)) == {(0, 1)}


def test_above_the_dense_limit_the_k_d_tree_answers(monkeypatch):
    rng = np.random.default_rng(5)
    pts = rng.uniform(-1, 1, size=(40, 6))
    dense = _pairs(close_pairs(pts, 1.0))
    monkeypatch.setattr(holdout_check, "DENSE_PAIRS_MAX_POSES", 10)
    assert _pairs(close_pairs(pts, 1.0)) == dense and dense
