"""Near-uniform viewpoints on a sphere or its upper half, and distances between them.

Viewpoints are points on a sphere of radius ``radius_m`` around a centre (the object's
centroid). Distances between viewpoints are great-circle (geodesic) lengths on that sphere, as the
camera travels over the viewsphere.
"""

from __future__ import annotations

import numpy as np

GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def fibonacci_directions(count: int, hemisphere: bool = False) -> np.ndarray:
    """Unit vectors, shape (count, 3), spread near-uniformly by a Fibonacci lattice.

    With ``hemisphere`` the points cover the upper half (z >= 0, the object stands on the floor);
    the first point is the one nearest the pole. Equal steps in z give equal areas, so the
    lattice is uniform in area on the sphere and on the hemisphere alike.

    Args:
        count: How many directions (at least 1).
        hemisphere: Cover only the upper half (z ≥ 0).

    Returns:
        (count, 3) unit vectors, the first nearest the pole (+Z).

    Raises:
        ValueError: ``count`` < 1.

    Example:
        >>> directions = fibonacci_directions(4, hemisphere=True)
        >>> directions.shape, bool((directions[:, 2] > 0).all())
        ((4, 3), True)
        >>> directions[:, 2].tolist()  # equal steps in z: equal areas
        [0.875, 0.625, 0.375, 0.125]
    """
    if count < 1:
        raise ValueError(f"viewpoint count must be at least 1, got {count}")
    i = np.arange(count, dtype=np.float64)
    z = 1.0 - (i + 0.5) / count if hemisphere else 1.0 - 2.0 * (i + 0.5) / count
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    phi = i * GOLDEN_ANGLE
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def azimuth_zenith(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Azimuth about +Z from +X and angle from the zenith, radians, of unit directions (n, 3).

    The coordinates the hemisphere figures plot (polar: azimuth, zenith angle).
    """
    directions = np.asarray(directions, dtype=np.float64)
    azimuth = np.arctan2(directions[:, 1], directions[:, 0])
    zenith = np.arccos(np.clip(directions[:, 2], -1.0, 1.0))
    return azimuth, zenith


def viewpoints(
    count: int,
    radius_m: float,
    hemisphere: bool = False,
    centre: np.ndarray | None = None,
) -> np.ndarray:
    """Camera positions, shape (count, 3), in metres on the viewsphere around ``centre``.

    The training viewsphere and the test viewpoints X_rho are made this way.

    Args:
        count: How many viewpoints.
        radius_m: The viewsphere's radius in metres (> 0).
        hemisphere: Only the upper half (the object stands on the floor).
        centre: (3,) the sphere's centre in metres (default the origin).

    Returns:
        (count, 3) positions in metres (:func:`fibonacci_directions` scaled and shifted).

    Raises:
        ValueError: ``radius_m`` ≤ 0 or ``count`` < 1.

    Example:
        >>> import numpy as np
        >>> positions = viewpoints(3, 0.5, hemisphere=True, centre=np.array([0.0, 0.0, 0.1]))
        >>> np.linalg.norm(positions - [0.0, 0.0, 0.1], axis=1).round(6).tolist()
        [0.5, 0.5, 0.5]
    """
    if radius_m <= 0:
        raise ValueError(f"viewsphere radius must be positive, got {radius_m} m")
    centre = np.zeros(3) if centre is None else np.asarray(centre, dtype=np.float64)
    return centre + radius_m * fibonacci_directions(count, hemisphere)


def geodesic_distance_matrix(points: np.ndarray, radius_m: float | None = None) -> np.ndarray:
    """Great-circle distances (count, count) between points on a sphere around the origin.

    ``points`` may be unit directions or positions relative to the sphere's centre; the
    distance is the angle times ``radius_m`` (by default the points' mean norm).

    Args:
        points: (count, 3) directions or positions (none at the centre).
        radius_m: The sphere's radius in metres, or None for the points' mean norm.

    Returns:
        (count, count) symmetric distances in metres, 0 on the diagonal.

    Raises:
        ValueError: A point lies at the centre.

    Example:
        >>> import numpy as np
        >>> points = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
        >>> geodesic_distance_matrix(points, radius_m=2.0).round(4).tolist()
        [[0.0, 3.1416, 6.2832], [3.1416, 0.0, 3.1416], [6.2832, 3.1416, 0.0]]
    """
    points = np.asarray(points, dtype=np.float64)
    norms = np.linalg.norm(points, axis=1)
    if np.any(norms <= 0):
        raise ValueError("a viewpoint lies at the sphere's centre; distances are undefined")
    directions = points / norms[:, None]
    radius = float(norms.mean()) if radius_m is None else float(radius_m)
    # atan2 of |a x b| and a.b is accurate for tiny and near-antipodal angles alike.
    cross = np.linalg.norm(np.cross(directions[:, None, :], directions[None, :, :]), axis=2)
    dot = directions @ directions.T
    angles = np.arctan2(cross, dot)
    np.fill_diagonal(angles, 0.0)
    return radius * angles


def k_nearest(distances: np.ndarray, k: int, allowed: np.ndarray | None = None) -> np.ndarray:
    """Indices (count, k) of each viewpoint's k nearest others, nearest first.

    ``allowed`` (bool, count) removes viewpoints from the candidates (e.g. unreachable ones);
    a row with fewer than k allowed neighbours is padded with -1.

    Args:
        distances: (count, count) distances (:func:`geodesic_distance_matrix`).
        k: Neighbours per viewpoint (at least 1).
        allowed: (count,) bool: the viewpoints that may be neighbours (None: all).

    Returns:
        (count, k) indices, nearest first, -1 where there are fewer than k.

    Raises:
        ValueError: ``distances`` is not square, or ``k`` < 1.

    Example:
        >>> import numpy as np
        >>> distances = np.array([[0.0, 1.0, 2.0], [1.0, 0.0, 1.5], [2.0, 1.5, 0.0]])
        >>> k_nearest(distances, 1).tolist()
        [[1], [0], [1]]
        >>> k_nearest(distances, 2, allowed=np.array([True, False, True])).tolist()
        [[2, -1], [0, 2], [0, -1]]
    """
    distances = np.asarray(distances, dtype=np.float64)
    n = distances.shape[0]
    if distances.shape != (n, n):
        raise ValueError(f"distance matrix must be square, got shape {distances.shape}")
    if k < 1:
        raise ValueError(f"k must be at least 1, got {k}")
    masked = distances.copy()
    np.fill_diagonal(masked, np.inf)
    if allowed is not None:
        masked[:, ~np.asarray(allowed, dtype=bool)] = np.inf
    k_eff = min(k, n - 1)
    order = np.argsort(masked, axis=1, kind="stable")[:, :k_eff]
    picked = np.take_along_axis(masked, order, axis=1)
    order = np.where(np.isfinite(picked), order, -1)
    if k_eff < k:
        order = np.pad(order, ((0, 0), (0, k - k_eff)), constant_values=-1)
    return order
