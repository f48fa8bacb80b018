import numpy as np
import pytest

from rapomdp.geometry.viewsphere import (
    azimuth_zenith,
    fibonacci_directions,
    geodesic_distance_matrix,
    k_nearest,
    viewpoints,
)


@pytest.mark.parametrize("hemisphere", [False, True])
@pytest.mark.parametrize("count", [16, 100, 128])
def test_viewpoints_count_radius_and_spread(count: int, hemisphere: bool) -> None:
    centre = np.array([0.1, -0.2, 0.15])
    points = viewpoints(count, 0.6, hemisphere=hemisphere, centre=centre)
    assert points.shape == (count, 3)
    np.testing.assert_allclose(np.linalg.norm(points - centre, axis=1), 0.6, atol=1e-12)
    if hemisphere:
        assert np.all(points[:, 2] >= centre[2])
    # near-uniform: every point's nearest neighbour is at a similar distance, close to the
    # spacing of a perfect packing (area per point = sqrt(A / n))
    area = (2.0 if hemisphere else 4.0) * np.pi * 0.6**2
    spacing = np.sqrt(area / count)
    distances = geodesic_distance_matrix(points - centre, 0.6)
    np.fill_diagonal(distances, np.inf)
    nearest = distances.min(axis=1)
    assert nearest.min() > 0.5 * spacing
    assert nearest.max() < 1.5 * spacing


def test_hemisphere_starts_at_the_pole() -> None:
    directions = fibonacci_directions(128, hemisphere=True)
    assert np.argmax(directions[:, 2]) == 0
    assert directions[0, 2] > 0.99


def test_geodesic_distance_is_angle_times_radius() -> None:
    points = np.array([[0.6, 0, 0], [0, 0.6, 0], [-0.6, 0, 0], [0, 0, 0.6]])
    d = geodesic_distance_matrix(points, 0.6)
    np.testing.assert_allclose(d[0, 1], 0.6 * np.pi / 2)
    np.testing.assert_allclose(d[0, 2], 0.6 * np.pi)
    np.testing.assert_allclose(np.diag(d), 0.0)
    np.testing.assert_allclose(d, d.T)
    # the triangle inequality holds for every triple
    assert np.all(d[:, None, :] <= d[:, :, None] + d[None, :, :] + 1e-12)


def test_k_nearest_orders_by_distance_and_skips_disallowed() -> None:
    points = viewpoints(32, 0.6, hemisphere=True)
    d = geodesic_distance_matrix(points, 0.6)
    nearest = k_nearest(d, 8)
    assert nearest.shape == (32, 8)
    assert not np.any(nearest == np.arange(32)[:, None])
    picked = np.take_along_axis(d, nearest, axis=1)
    assert np.all(np.diff(picked, axis=1) >= 0)
    allowed = np.ones(32, dtype=bool)
    allowed[nearest[0, 0]] = False
    assert nearest[0, 0] not in k_nearest(d, 8, allowed)[0]


def test_k_nearest_pads_when_too_few_allowed() -> None:
    d = geodesic_distance_matrix(viewpoints(5, 0.6), 0.6)
    allowed = np.array([True, True, False, False, False])
    assert k_nearest(d, 3, allowed)[0].tolist() == [1, -1, -1]


def test_bad_counts_are_refused() -> None:
    with pytest.raises(ValueError, match="at least 1"):
        fibonacci_directions(0)
    with pytest.raises(ValueError, match="radius must be positive"):
        viewpoints(10, 0.0)


def test_azimuth_zenith_of_known_directions() -> None:
    azimuth, zenith = azimuth_zenith(np.array([[0, 0, 1.0], [1.0, 0, 0], [0, -1.0, 0],
                                               [0.5, 0.5, np.sqrt(0.5)]]))
    np.testing.assert_allclose(zenith, [0, np.pi / 2, np.pi / 2, np.pi / 4], atol=1e-12)
    np.testing.assert_allclose(azimuth[1:], [0, -np.pi / 2, np.pi / 4], atol=1e-12)
