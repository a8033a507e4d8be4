"""A persistent voxel grid that averages points per voxel, updated one view at a time.

The paper downsamples its growing cloud at 1 mm whenever it passes 100k points, which compounds
centroid drift and re-reads every point each time. Summing points, colours and counts per voxel
of a fixed grid gives, after any number of views, exactly the mean of all points in each voxel:
the single downsample of the concatenated cloud, while streaming and in bounded memory.
"""

from __future__ import annotations

import numpy as np

from agrisim.interfaces import Cloud

_BITS = 21
_OFFSET = 1 << (_BITS - 1)
_LIMIT = _OFFSET - 1


def voxel_keys(points: np.ndarray, size: float) -> np.ndarray:
    """One int64 key per point: its voxel's integer coordinates (origin-aligned grid) packed
    21 bits each, so keys sort and compare like the coordinates."""
    idx = np.floor(points / size).astype(np.int64)
    if idx.size and (idx.min() < -_LIMIT or idx.max() > _LIMIT):
        raise ValueError(f"points lie beyond the voxel grid's reach of {_LIMIT * size:g} m from the origin")
    idx += _OFFSET
    return (idx[:, 0] << (2 * _BITS)) | (idx[:, 1] << _BITS) | idx[:, 2]


def _reduce(keys: np.ndarray, *columns: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
    """Unique keys, count per key, and per-key sums of each (N x C) column block."""
    unique, inverse = np.unique(keys, return_inverse=True)
    n = len(unique)
    counts = np.bincount(inverse, minlength=n)
    sums = [
        np.column_stack([np.bincount(inverse, weights=block[:, j], minlength=n) for j in range(block.shape[1])])
        if n
        else np.zeros((0, block.shape[1]))
        for block in columns
    ]
    return unique, counts, sums


class VoxelGrid:
    """Per-voxel sums of points and colours on a grid of ``size`` metres."""

    def __init__(self, size: float) -> None:
        if not size > 0:
            raise ValueError(f"voxel size must be positive, got {size}")
        self.size = float(size)
        self.keys = np.zeros(0, np.int64)  # sorted
        self.counts = np.zeros(0, np.int64)
        self.point_sums = np.zeros((0, 3))
        self.color_sums = np.zeros((0, 3))

    def __len__(self) -> int:
        return len(self.keys)

    def add(self, points: np.ndarray, colors: np.ndarray) -> Cloud:
        """Add points (N x 3) with colours (N x 3 uint8); returns them averaged per voxel (the
        view's own downsampled cloud)."""
        keys, counts, (psum, csum) = _reduce(voxel_keys(points, self.size), points, colors.astype(np.float64))
        pos = np.searchsorted(self.keys, keys)
        found = np.zeros(len(keys), bool)
        inside = pos < len(self.keys)
        found[inside] = self.keys[pos[inside]] == keys[inside]
        at = pos[found]
        self.counts[at] += counts[found]
        self.point_sums[at] += psum[found]
        self.color_sums[at] += csum[found]
        new = ~found
        self.keys = np.insert(self.keys, pos[new], keys[new])
        self.counts = np.insert(self.counts, pos[new], counts[new])
        self.point_sums = np.insert(self.point_sums, pos[new], psum[new], axis=0)
        self.color_sums = np.insert(self.color_sums, pos[new], csum[new], axis=0)
        return _cloud(counts, psum, csum)

    def cloud(self) -> Cloud:
        """The mean point and colour of every occupied voxel, in key order."""
        return _cloud(self.counts, self.point_sums, self.color_sums)

    @classmethod
    def union(cls, grids: list[VoxelGrid]) -> VoxelGrid:
        """One grid holding the points of all ``grids`` (same voxel size): a voxel's mean over
        the union, not a mean of means."""
        out = cls(grids[0].size if grids else 1.0)
        if not grids:
            return out
        keys = np.concatenate([g.keys for g in grids])
        counts = np.concatenate([g.counts for g in grids]).astype(np.float64)[:, None]
        psum = np.concatenate([g.point_sums for g in grids])
        csum = np.concatenate([g.color_sums for g in grids])
        out.keys, _, (count, out.point_sums, out.color_sums) = _reduce(keys, counts, psum, csum)
        out.counts = np.rint(count[:, 0]).astype(np.int64)  # sums of whole numbers: exact
        return out


def _cloud(counts: np.ndarray, point_sums: np.ndarray, color_sums: np.ndarray) -> Cloud:
    n = np.maximum(counts, 1)[:, None]
    colors = np.clip(np.rint(color_sums / n), 0, 255).astype(np.uint8)
    return Cloud(point_sums / n, colors)
