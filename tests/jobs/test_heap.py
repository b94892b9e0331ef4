"""campaign/jobs/heap.py and the large import's memory-lean helpers: what they return is
what the plain numpy/pyarrow calls they replace return."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest

from analysis.identification.io.model_export import _first_of_groups
from campaign.jobs import heap


def test_arrow_on_c_heap_sets_and_restores_the_pool():
    before = pa.default_memory_pool().backend_name
    with heap.arrow_on_c_heap():
        assert pa.default_memory_pool().backend_name == "system"
        assert pa.array(np.arange(1000.0)).sum().as_py() == 499500.0
    assert pa.default_memory_pool().backend_name == before


def test_arrow_on_c_heap_restores_the_pool_after_an_error():
    before = pa.default_memory_pool().backend_name
    with pytest.raises(ZeroDivisionError), heap.arrow_on_c_heap():
        1 / 0  # noqa: B018
    assert pa.default_memory_pool().backend_name == before


@pytest.mark.parametrize("group", [
    np.array([0]), np.array([5, 5, 2, 9, 2]), np.repeat(np.arange(7), 3),
    np.random.default_rng(0).integers(0, 50, 1000),
    np.random.default_rng(1).integers(0, 5000, 200_000),  # several blocks of 65536
    np.random.default_rng(2).integers(0, 10**6, 1000),  # sparse labels: np.unique's path
    np.array([3, -1, 3]),  # negative labels: np.unique's path
])
def test_first_of_groups_is_np_unique_return_index(group):
    assert np.array_equal(_first_of_groups(group), np.unique(group, return_index=True)[1])
