import numpy as np
import pytest

from rapomdp.geometry.voxels import VoxelGrid


def test_points_land_in_the_voxel_whose_centre_is_nearest() -> None:
    grid = VoxelGrid.around(np.array([-0.2, -0.2, 0.0]), np.array([0.2, 0.2, 0.4]), 40)
    assert grid.voxel_size_m == pytest.approx(0.01)
    rng = np.random.default_rng(1)
    points = rng.uniform([-0.2, -0.2, 0.0], [0.2, 0.2, 0.4], size=(500, 3))
    idx, inside = grid.points_to_indices(points)
    assert inside.all()
    centres = grid.indices_to_centres(idx)
    assert np.all(np.abs(points - centres) <= grid.voxel_size_m / 2 + 1e-12)
    np.testing.assert_array_equal(grid.unflat(grid.flat(idx)), idx)


def test_known_point_and_outside_points() -> None:
    grid = VoxelGrid(origin=(0.0, 0.0, 0.0), voxel_size_m=0.1, shape=(3, 3, 3))
    idx, inside = grid.points_to_indices(np.array([[0.15, 0.25, 0.05], [0.35, 0.0, 0.0],
                                                   [-0.01, 0.1, 0.1]]))
    assert idx[0].tolist() == [1, 2, 0]
    assert inside.tolist() == [True, False, False]
    np.testing.assert_allclose(grid.indices_to_centres(np.array([[1, 2, 0]])),
                               [[0.15, 0.25, 0.05]])


def test_bad_grids_are_refused() -> None:
    with pytest.raises(ValueError, match="voxel size must be positive"):
        VoxelGrid((0, 0, 0), 0.0, (1, 1, 1))
    with pytest.raises(ValueError, match="resolution must be at least 1"):
        VoxelGrid.around(np.zeros(3), np.ones(3), 0)
