"""The placement grid, never materialised: rows are made a chunk at a time.

A search box of x, y, z (m) and yaw (rad) values has ``nx ny nz nyaw``
placements; with 1 mm steps that is 1e8-1e9 rows, 3-30 GB as one (P, 4) array.
:class:`PlacementGrid` keeps the four axes and makes the rows of any range of
placement indices on demand, in the order of ``np.meshgrid(..., indexing="ij")``
flattened (x slowest, yaw fastest), so a chunked search holds one chunk of
placements at a time and gives the same results, in the same order, as one over
the full array.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlacementGrid:
    """Axes of the placement grid: x, y, z (m) and yaw (rad), each 1-D."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    yaw: np.ndarray

    @property
    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return self.x, self.y, self.z, self.yaw

    @property
    def shape(self) -> tuple[int, int, int, int]:
        """Values per axis (nx, ny, nz, nyaw)."""
        return tuple(int(a.size) for a in self.axes)  # type: ignore[return-value]

    def __len__(self) -> int:
        """Number of placements (a Python int: no overflow)."""
        n = 1
        for s in self.shape:
            n *= s
        return n

    def rows(self, start: int, stop: int) -> np.ndarray:
        """Placements ``start:stop`` as a (stop - start, 4) array [x, y, z, yaw] (m, rad)."""
        stop = min(stop, len(self))
        index = np.arange(start, max(start, stop), dtype=np.int64)
        parts = np.unravel_index(index, self.shape)
        return np.stack([a[i] for a, i in zip(self.axes, parts, strict=True)], axis=-1)

    def __getitem__(self, item):
        """One placement (4,) by index, or the rows of a slice (step 1)."""
        if isinstance(item, slice):
            start, stop, step = item.indices(len(self))
            if step != 1:
                raise ValueError("PlacementGrid slices take step 1")
            return self.rows(start, stop)
        i = int(item)
        if i < 0:
            i += len(self)
        if not 0 <= i < len(self):
            raise IndexError(f"placement {item} of {len(self)}")
        return self.rows(i, i + 1)[0]

    def full(self) -> np.ndarray:
        """Every placement as one (P, 4) array (small grids and tests only)."""
        return self.rows(0, len(self))
