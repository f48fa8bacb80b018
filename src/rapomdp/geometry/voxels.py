"""A regular voxel grid: points to voxel indices and voxel indices to centres."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class VoxelGrid:
    """Axis-aligned cubic voxels of edge ``voxel_size_m``; ``origin`` is the grid's min corner.

    The grid of the 3D saliency volume. :meth:`around` fits one to a bounding box.

    Attributes:
        origin: (x, y, z) of the grid's min corner in metres.
        voxel_size_m: The voxels' edge in metres.
        shape: Voxels along x, y and z.

    Example:
        >>> import numpy as np
        >>> grid = VoxelGrid.around(np.zeros(3), np.ones(3), resolution=4)
        >>> grid.voxel_size_m, grid.shape, grid.count
        (0.25, (5, 5, 5), 125)
        >>> indices, inside = grid.points_to_indices(np.array([[0.5, 0.5, 0.5], [2.0, 2.0, 2.0]]))
        >>> indices[0].tolist(), inside.tolist(), grid.indices_to_centres(indices[:1]).tolist()
        ([2, 2, 2], [True, False], [[0.5, 0.5, 0.5]])
    """

    origin: tuple[float, float, float]
    voxel_size_m: float
    shape: tuple[int, int, int]

    def __post_init__(self) -> None:
        if self.voxel_size_m <= 0:
            raise ValueError(f"voxel size must be positive, got {self.voxel_size_m} m")
        if len(self.shape) != 3 or min(self.shape) < 1:
            raise ValueError(f"voxel grid shape must be three positive counts, got {self.shape}")

    @classmethod
    def around(cls, lower: np.ndarray, upper: np.ndarray, resolution: int) -> VoxelGrid:
        """The grid of ``resolution`` voxels along the longest side of a bounding box.

        The box is padded by half a voxel so points on its faces fall inside.
        """
        if resolution < 1:
            raise ValueError(f"voxel resolution must be at least 1, got {resolution}")
        lower = np.asarray(lower, dtype=np.float64)
        upper = np.asarray(upper, dtype=np.float64)
        extent = upper - lower
        if np.any(extent < 0):
            raise ValueError("bounding box upper corner lies below its lower corner")
        size = max(float(extent.max()), 1e-9) / resolution
        shape = np.maximum(np.ceil(extent / size - 1e-9).astype(int), 1) + 1
        centre = (lower + upper) / 2.0
        origin = centre - shape * size / 2.0
        nx, ny, nz = (int(s) for s in shape)
        return cls(tuple(origin.tolist()), size, (nx, ny, nz))

    @property
    def count(self) -> int:
        return int(np.prod(self.shape))

    def points_to_indices(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Integer voxel indices (n, 3) of points (n, 3) and a mask of those inside the grid."""
        points = np.asarray(points, dtype=np.float64)
        idx = np.floor((points - np.asarray(self.origin)) / self.voxel_size_m).astype(np.int64)
        inside = np.all((idx >= 0) & (idx < np.asarray(self.shape)), axis=-1)
        return idx, inside

    def indices_to_centres(self, indices: np.ndarray) -> np.ndarray:
        """World coordinates (n, 3) of the centres of voxels (n, 3)."""
        indices = np.asarray(indices, dtype=np.float64)
        return np.asarray(self.origin) + (indices + 0.5) * self.voxel_size_m

    def flat(self, indices: np.ndarray) -> np.ndarray:
        """Flat (C-order) voxel numbers of voxel indices (n, 3)."""
        return np.ravel_multi_index(tuple(np.asarray(indices).T), self.shape)

    def unflat(self, flat: np.ndarray) -> np.ndarray:
        """Voxel indices (n, 3) of flat voxel numbers."""
        return np.stack(np.unravel_index(np.asarray(flat), self.shape), axis=-1)

    def to_dict(self) -> dict[str, object]:
        return {
            "origin": list(self.origin),
            "voxel_size_m": self.voxel_size_m,
            "shape": list(self.shape),
        }
