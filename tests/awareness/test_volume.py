"""The saliency volume, visibility and viewpoint scores on hand-checked geometry."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.volume import SaliencyVolume, saliency_volume, segment_medians
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








