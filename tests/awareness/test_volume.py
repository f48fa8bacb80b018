"""The saliency volume, visibility and viewpoint scores on hand-checked geometry."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from rapomdp.awareness.scores import normalise_scores, viewpoint_scores
from rapomdp.awareness.visibility import render_visibility, visibility_from_depth
from rapomdp.awareness.volume import SaliencyVolume, saliency_volume, segment_medians
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import Intrinsics, look_at_many
from rapomdp.geometry.voxels import VoxelGrid

TINY = Intrinsics(width=5, height=5, fx=5.0, fy=5.0, cx=2.0, cy=2.0)
GRID = VoxelGrid.around(np.full(3, -1.0), np.full(3, 1.0), 4)  # 0.5 m voxels, origin -1.25


def side_camera() -> np.ndarray:
    """A camera at x = 1 m looking at the origin: right = -y, down = -z, forward = -x."""
    return look_at_many(np.array([[1.0, 0.0, 0.0]]))


def test_grid_is_what_the_tests_assume():
    assert GRID.voxel_size_m == pytest.approx(0.5) and GRID.shape == (5, 5, 5)
    assert GRID.origin == pytest.approx((-1.25, -1.25, -1.25))


def test_known_depth_pixel_lands_in_the_right_voxel(tmp_path):
    depth = np.zeros((1, 5, 5))
    saliency = np.zeros((1, 5, 5))
    # pixel (u=4, v=1) at 0.5 m: camera point (0.2, -0.1, 0.5) -> world (0.5, -0.2, 0.1)
    depth[0, 1, 4] = 0.5
    saliency[0, 1, 4] = 0.7
    volume = saliency_volume(depth, side_camera(), saliency, TINY, GRID)
    # world (0.5, -0.2, 0.1) - origin = (1.75, 1.05, 1.35) -> voxel (3, 2, 2)
    assert volume.counts[3, 2, 2] == 1 and volume.counts.sum() == 1
    assert volume.scores[3, 2, 2] == pytest.approx(0.7)
    assert np.isnan(volume.scores).sum() == GRID.count - 1  # every other voxel is empty
    volume.save(tmp_path / "v.npz")
    loaded = SaliencyVolume.load(tmp_path / "v.npz")
    assert loaded.grid == GRID and loaded.scores[3, 2, 2] == pytest.approx(0.7)


def test_voxel_score_is_the_median_of_its_points():
    # four views of the same pixel at the same depth: one voxel, four saliency values
    depth = np.zeros((4, 5, 5))
    depth[:, 2, 2] = 0.9  # world (0.1, 0, 0), voxel (2, 2, 2)
    saliency = np.zeros((4, 5, 5))
    saliency[:, 2, 2] = [0.1, 0.9, 0.3, 0.5]
    poses = np.repeat(side_camera(), 4, axis=0)
    even = saliency_volume(depth, poses, saliency, TINY, GRID)
    assert even.scores[2, 2, 2] == pytest.approx(0.4) and even.counts[2, 2, 2] == 4
    odd = saliency_volume(depth[:3], poses[:3], saliency[:3], TINY, GRID)
    assert odd.scores[2, 2, 2] == pytest.approx(0.3)


def test_segment_medians_match_numpy():
    rng = np.random.default_rng(0)
    keys = rng.integers(0, 30, 500)
    values = rng.random(500)
    unique, medians, counts = segment_medians(keys, values)
    for key, median, count in zip(unique, medians, counts, strict=True):
        assert median == pytest.approx(np.median(values[keys == key]))
        assert count == np.sum(keys == key)


def test_saliency_maps_must_match_depth():
    with pytest.raises(ValueError, match="do not match depth images"):
        saliency_volume(np.zeros((1, 5, 5)), side_camera(), np.zeros((1, 4, 5)), TINY, GRID)


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


def test_viewpoint_score_is_the_mean_of_visible_scored_voxels():
    depth = np.zeros((2, 5, 5))
    depth[0, 2, 2] = 0.9  # view 0 sees voxel (2, 2, 2)
    depth[1, 1, 4] = 0.5  # view 1 sees voxel (3, 2, 2)
    depth[1, 2, 2] = 0.9  # ... and voxel (2, 2, 2)
    vis = visibility_from_depth(depth, np.repeat(side_camera(), 2, axis=0), TINY, GRID)
    scores = np.full(GRID.shape, np.nan)
    scores[2, 2, 2], scores[3, 2, 2] = 0.2, 0.6
    out = viewpoint_scores(vis, scores.reshape(-1))
    assert out == pytest.approx([0.2, 0.4])
    scores[3, 2, 2] = np.nan  # an empty voxel does not count
    assert viewpoint_scores(vis, scores.reshape(-1)) == pytest.approx([0.2, 0.2])


def test_scores_normalise_per_class_to_unit_range():
    out = normalise_scores(np.array([[0.2, 0.4, 0.3], [0.5, 0.5, 0.5], [1.0, np.nan, 3.0]]))
    assert out[0] == pytest.approx([0.0, 1.0, 0.5])
    assert out[1] == pytest.approx([0.5, 0.5, 0.5])
    assert out[2] == pytest.approx([0.0, 0.0, 1.0])
