"""Voxel visibility from depth renders."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from rapomdp.awareness.visibility import render_visibility
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import Intrinsics, look_at_many
from rapomdp.geometry.voxels import VoxelGrid


@pytest.fixture(scope="module")
def box_renderer():
    mesh = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    return DepthRenderer(mesh, Intrinsics(width=64, height=48, fx=60.0, fy=60.0, cx=31.5,
                                          cy=23.5))


def test_voxel_facing_the_camera_is_visible_and_one_behind_is_not(box_renderer):
    grid = VoxelGrid.around(np.full(3, -0.1), np.full(3, 0.1), 10)
    eyes = np.array([[0.6, 0.0, 0.0], [-0.6, 0.0, 0.0]])
    vis = render_visibility(box_renderer, look_at_many(eyes), grid).toarray()
    front = grid.flat(grid.points_to_indices(np.array([[0.099, 0.0, 0.0]]))[0])[0]
    back = grid.flat(grid.points_to_indices(np.array([[-0.099, 0.0, 0.0]]))[0])[0]
    inside = grid.flat(grid.points_to_indices(np.array([[0.0, 0.0, 0.0]]))[0])[0]
    assert vis[0, front] and not vis[0, back] and not vis[0, inside]
    assert vis[1, back] and not vis[1, front]
    assert vis.dtype == bool and vis.shape == (2, grid.count)
