"""The 3D dense saliency volume (paper Sec. 4.2, Fig. 1c).

Every pixel with depth of every view is back-projected to the world point it saw, carrying that
pixel's 2D saliency; each voxel of a grid around the object scores the *median* saliency of the
points inside it; a voxel without points is empty (NaN).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.geometry.camera import Intrinsics, back_project
from rapomdp.geometry.voxels import VoxelGrid
from rapomdp.io import load_npz, save_npz


@dataclass
class SaliencyVolume:
    """Voxel scores (grid.shape) in [0, 1], NaN where empty, and the points per voxel."""

    grid: VoxelGrid
    scores: np.ndarray
    counts: np.ndarray

    @property
    def occupied(self) -> np.ndarray:
        """Boolean (grid.shape): voxels holding at least one point."""
        return self.counts > 0

    def flat_scores(self) -> np.ndarray:
        return self.scores.reshape(-1)

    def save(self, path: str | Path, **extra: np.ndarray) -> None:
        save_npz(
            path, compressed=True, scores=self.scores.astype(np.float32),
            counts=self.counts.astype(np.int32), origin=np.asarray(self.grid.origin),
            voxel_size_m=np.float64(self.grid.voxel_size_m),
            shape=np.asarray(self.grid.shape, dtype=np.int64), **extra,
        )

    @classmethod
    def load(cls, path: str | Path) -> SaliencyVolume:
        data = load_npz(path)
        grid = VoxelGrid(tuple(data["origin"].tolist()), float(data["voxel_size_m"]),
                         tuple(int(s) for s in data["shape"]))
        return cls(grid, data["scores"], data["counts"])


def segment_medians(keys: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                   np.ndarray]:
    """Median of ``values`` per distinct ``key``, vectorised: sort by (key, value), then take
    the middle element(s) of each run. Returns (unique keys, medians, counts)."""
    keys = np.asarray(keys)
    values = np.asarray(values, dtype=np.float64)
    if keys.size == 0:
        return keys[:0], values[:0], np.zeros(0, dtype=np.int64)
    order = np.lexsort((values, keys))
    keys, values = keys[order], values[order]
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    counts = np.diff(np.r_[starts, keys.size])
    lower = values[starts + (counts - 1) // 2]
    upper = values[starts + counts // 2]
    return keys[starts], (lower + upper) / 2.0, counts


def saliency_points(depth_m: np.ndarray, poses: np.ndarray, saliency: np.ndarray,
                    intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """World points (n, 3) of every pixel with depth, and the saliency (n,) each carries."""
    depth_m = np.asarray(depth_m)
    saliency = np.asarray(saliency)
    if saliency.shape != depth_m.shape:
        raise ValueError(f"saliency maps {saliency.shape} do not match depth images "
                         f"{depth_m.shape}")
    valid = depth_m > 0
    points = back_project(depth_m, poses, intrinsics)[valid]
    return points, saliency[valid].astype(np.float64)


def saliency_volume(depth_m: np.ndarray, poses: np.ndarray, saliency: np.ndarray,
                    intrinsics: Intrinsics, grid: VoxelGrid) -> SaliencyVolume:
    """The saliency volume on ``grid`` from views (n, H, W) of depth, poses and 2D saliency."""
    points, values = saliency_points(depth_m, poses, saliency, intrinsics)
    indices, inside = grid.points_to_indices(points)
    flat = grid.flat(indices[inside]) if inside.any() else np.zeros(0, dtype=np.int64)
    keys, medians, counts = segment_medians(flat, values[inside])
    scores = np.full(grid.count, np.nan)
    scores[keys] = medians
    per_voxel = np.zeros(grid.count, dtype=np.int64)
    per_voxel[keys] = counts
    return SaliencyVolume(grid, scores.reshape(grid.shape), per_voxel.reshape(grid.shape))


def object_grid(lower: np.ndarray, upper: np.ndarray, resolution: int) -> VoxelGrid:
    """The voxel grid over an object's bounding box, ``resolution`` voxels on its longest side."""
    return VoxelGrid.around(lower, upper, resolution)
