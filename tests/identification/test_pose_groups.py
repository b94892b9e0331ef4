"""Pose grouping without pairwise comparison equals the pairwise reference."""

from __future__ import annotations

import numpy as np
import pytest

from analysis.identification.poses import group_names, pose_groups, pose_groups_pairwise

TOL = 1.0


def _same_partition(a: np.ndarray, b: np.ndarray) -> None:
    # both number groups by first appearance, so equal partitions give equal arrays
    np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("seed", range(6))
def test_clusters_with_jitter_equal_pairwise(seed):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-20, 20, (12, 6))
    q = centres[rng.integers(0, 12, 300)] + 0.05 * rng.normal(size=(300, 6))
    _same_partition(pose_groups(q, TOL), pose_groups_pairwise(q, TOL))
    assert pose_groups(q, TOL).max() + 1 == len(np.unique(pose_groups_pairwise(q, TOL)))


@pytest.mark.parametrize("seed", range(6))
def test_chains_across_cell_boundaries_equal_pairwise(seed):
    """Chains of readings 0.9 tol apart (longer than tol, so no grid cell holds them),
    straddling multiples of tol, in one joint or diagonally, plus near misses 1.05 tol."""
    rng = np.random.default_rng(100 + seed)
    parts = []
    for _ in range(8):
        start = np.round(rng.uniform(-10, 10, 6)) + rng.choice([-1e-9, 0.0, 1e-9])
        step = np.zeros(6)
        step[rng.integers(0, 6, rng.integers(1, 4))] = rng.choice([0.9, 1.0, 1.05])
        n = rng.integers(2, 9)
        parts.append(start + np.arange(n)[:, None] * step)
    q = np.concatenate(parts)
    q = q[rng.permutation(len(q))]
    _same_partition(pose_groups(q, TOL), pose_groups_pairwise(q, TOL))


def test_gap_splitting_is_not_enough():
    """Every sorted gap <= tol, yet (0, 0) links to nothing: the exact sweep must see it."""
    q = np.array([[0.0, 0.0], [0.9, 1.8], [1.8, 0.9]])
    np.testing.assert_array_equal(pose_groups(q, TOL), [0, 1, 1])
    np.testing.assert_array_equal(pose_groups_pairwise(q, TOL), [0, 1, 1])


@pytest.mark.parametrize("seed", range(4))
def test_dense_random_points_equal_pairwise(seed):
    rng = np.random.default_rng(200 + seed)
    q = rng.uniform(0, 4, (250, 3))
    _same_partition(pose_groups(q, TOL), pose_groups_pairwise(q, TOL))


def test_exact_tolerance_is_a_link():
    q = np.array([[0.0, 0.0], [0.5, 0.5], [1.5, 0.5]])  # differences exactly tol are links
    np.testing.assert_array_equal(pose_groups(q, TOL), pose_groups_pairwise(q, TOL))
    np.testing.assert_array_equal(pose_groups(q, TOL), [0, 0, 0])


def test_group_names_in_order_of_appearance():
    labels = np.array(["b", "a", "b", "c", "a", "d"])
    group = np.array([1, 0, 1, 0, 0, 2])
    assert group_names(labels, group) == ["a+c", "b", "d"]


def test_factorize_labels_by_blocks_numbers_text_in_order_of_appearance():
    import pandas as pd

    from analysis.identification.poses import factorize_labels

    rng = np.random.default_rng(2)
    pool = np.array([f"P{i}" for i in range(50)] + [7, "7"], dtype=object)  # 7 and "7": one
    labels = pool[rng.integers(0, len(pool), 1000)]
    codes, uniques = factorize_labels(labels, block=37)
    ref_codes, ref_uniques = pd.factorize(labels.astype(str))
    np.testing.assert_array_equal(codes, ref_codes)
    assert uniques == list(ref_uniques)
