"""Visibility eta(v, x): which voxels' surface a camera at viewpoint x sees.

The volume model is rendered from every viewpoint in one batch; each pixel with depth is
back-projected and marks the voxel it falls in. The result is a sparse boolean matrix
(viewpoints, voxels).
"""

from __future__ import annotations

import numpy as np
from scipy import sparse

from rapomdp.geometry.camera import Intrinsics, back_project
from rapomdp.geometry.voxels import VoxelGrid


def visibility_from_depth(depth_m: np.ndarray, poses: np.ndarray, intrinsics: Intrinsics,
                          grid: VoxelGrid) -> sparse.csr_matrix:
    """Sparse boolean (views, voxels): voxel v holds a surface point seen by view x.

    ``depth_m`` (views, H, W) are renders of the object from ``poses`` (views, 4, 4).
    """
    depth_m = np.asarray(depth_m)
    if depth_m.ndim == 2:
        depth_m, poses = depth_m[None], np.asarray(poses)[None]
    views = depth_m.shape[0]
    valid = depth_m > 0
    view_of = np.broadcast_to(np.arange(views)[:, None, None], depth_m.shape)[valid]
    points = back_project(depth_m, poses, intrinsics)[valid]
    indices, inside = grid.points_to_indices(points)
    rows = view_of[inside]
    cols = grid.flat(indices[inside]) if inside.any() else np.zeros(0, dtype=np.int64)
    matrix = sparse.csr_matrix((np.ones(rows.size, dtype=bool), (rows, cols)),
                               shape=(views, grid.count))
    matrix.sum_duplicates()
    matrix.data[:] = True
    return matrix


def render_visibility(renderer, poses: np.ndarray, grid: VoxelGrid) -> sparse.csr_matrix:  # noqa: ANN001
    """Visibility (views, voxels) of the renderer's mesh from ``poses``, one render batch."""
    return visibility_from_depth(renderer.render(poses), poses, renderer.intrinsics, grid)
