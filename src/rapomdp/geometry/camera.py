"""The pinhole depth camera: intrinsics, look-at poses, projection and back-projection.

Conventions (fixed for the whole project):

* camera frame as in OpenCV: x right, y down, z forward along the optical axis;
* a pose is the 4x4 camera-to-world transform ``T_wc`` (its last column is the camera centre);
* pixel (u, v) is column u, row v, with integer coordinates at pixel centres;
* depth images hold z-depth in metres (distance along the optical axis), 0 where nothing is hit.

These functions are the only place that derives poses, rays and projections.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

XTION_WIDTH_PX = 640
XTION_HEIGHT_PX = 480
XTION_HFOV_DEG = 58.0


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels for an image of ``width`` x ``height``.

    Attributes:
        width: Image width in pixels.
        height: Image height in pixels.
        fx: Horizontal focal length in pixels.
        fy: Vertical focal length in pixels.
        cx: Principal point's column (pixel centres at integers).
        cy: Principal point's row.

    Example:
        >>> camera = Intrinsics(64, 48, fx=57.7, fy=57.7, cx=31.5, cy=23.5)
        >>> [round(angle, 1) for angle in camera.fov_deg]
        [58.0, 45.2]
        >>> camera.scaled(128, 96).fx
        115.4
    """

    width: int
    height: int
    fx: float
    fy: float
    cx: float
    cy: float

    def __post_init__(self) -> None:
        if self.width < 1 or self.height < 1:
            raise ValueError(f"image size must be positive, got {self.width}x{self.height}")
        if self.fx <= 0 or self.fy <= 0:
            raise ValueError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 calibration matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def fov_deg(self) -> tuple[float, float]:
        """Horizontal and vertical field of view in degrees."""
        h = 2.0 * np.degrees(np.arctan(self.width / (2.0 * self.fx)))
        v = 2.0 * np.degrees(np.arctan(self.height / (2.0 * self.fy)))
        return float(h), float(v)

    def scaled(self, width: int, height: int) -> Intrinsics:
        """The same camera rendered at another resolution (same field of view)."""
        sx, sy = width / self.width, height / self.height
        return Intrinsics(
            width=width,
            height=height,
            fx=self.fx * sx,
            fy=self.fy * sy,
            cx=(self.cx + 0.5) * sx - 0.5,
            cy=(self.cy + 0.5) * sy - 0.5,
        )

    def to_dict(self) -> dict[str, float]:
        return {k: getattr(self, k) for k in ("width", "height", "fx", "fy", "cx", "cy")}


def xtion_intrinsics(width: int = XTION_WIDTH_PX, height: int = XTION_HEIGHT_PX) -> Intrinsics:
    """The Asus Xtion Pro Live depth camera (58 deg horizontal field of view, square pixels).

    At 640x480 the focal length is 320 / tan(29 deg) = 577.3 px, which gives a 45.1 deg
    vertical field of view (the specification says 45 deg). Other resolutions scale it.

    Args:
        width: Image width in pixels (the configuration's ``camera.width``).
        height: Image height in pixels.

    Returns:
        The intrinsics at that resolution, the same field of view.

    Example:
        >>> camera = xtion_intrinsics()
        >>> round(camera.fx, 1), [round(angle, 1) for angle in camera.fov_deg]
        (577.3, [58.0, 45.1])
        >>> xtion_intrinsics(64, 48).cx
        31.5
    """
    f = float((XTION_WIDTH_PX / 2.0) / np.tan(np.radians(XTION_HFOV_DEG / 2.0)))
    native = Intrinsics(
        width=XTION_WIDTH_PX,
        height=XTION_HEIGHT_PX,
        fx=f,
        fy=f,
        cx=(XTION_WIDTH_PX - 1) / 2.0,
        cy=(XTION_HEIGHT_PX - 1) / 2.0,
    )
    return native if (width, height) == (XTION_WIDTH_PX, XTION_HEIGHT_PX) else native.scaled(
        width, height
    )


def look_at_many(
    eyes: np.ndarray, target: np.ndarray | None = None, up: np.ndarray | None = None
) -> np.ndarray:
    """Camera-to-world poses (n, 4, 4) with each camera at ``eyes[i]`` looking at ``target``.

    The image's up direction is the world ``up`` (default +Z) projected onto the image plane.
    Where the optical axis is parallel to ``up`` (a camera at the pole), the pose is the limit
    reached by a camera approaching the pole from azimuth 0 (the +X side): image right is world
    +Y and image up is world -X. So the pose is well defined there and continuous along that
    meridian.

    Args:
        eyes: (n, 3) camera centres in metres.
        target: (3,) the point every camera looks at (default the origin).
        up: (3,) the world's up direction (default +Z).

    Returns:
        (n, 4, 4) camera-to-world transforms: columns image-right, image-down, optical axis,
        centre (OpenCV convention).

    Raises:
        ValueError: A camera sits at the target.

    Example:
        >>> import numpy as np
        >>> poses = look_at_many(np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]))
        >>> poses.shape, bool(np.allclose(poses[0, :3, 2], [-1.0, 0.0, 0.0]))  # axis to 0
        ((2, 4, 4), True)
    """
    eyes = np.atleast_2d(np.asarray(eyes, dtype=np.float64))
    target = np.zeros(3) if target is None else np.asarray(target, dtype=np.float64)
    up = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, dtype=np.float64)
    forward = target - eyes
    dist = np.linalg.norm(forward, axis=1, keepdims=True)
    if np.any(dist < 1e-12):
        raise ValueError("a camera sits at its target; the viewing direction is undefined")
    forward = forward / dist
    right = np.cross(forward, up)
    norm = np.linalg.norm(right, axis=1, keepdims=True)
    degenerate = norm[:, 0] < 1e-9
    if np.any(degenerate):
        fallback = np.cross(forward[degenerate], np.array([-1.0, 0.0, 0.0]))
        right[degenerate] = fallback
        norm[degenerate] = np.linalg.norm(fallback, axis=1, keepdims=True)
    right = right / norm
    down = np.cross(forward, right)
    poses = np.zeros((eyes.shape[0], 4, 4))
    poses[:, :3, 0] = right
    poses[:, :3, 1] = down
    poses[:, :3, 2] = forward
    poses[:, :3, 3] = eyes
    poses[:, 3, 3] = 1.0
    return poses


def look_at(eye: np.ndarray, target: np.ndarray | None = None) -> np.ndarray:
    """One camera-to-world pose (4, 4); see :func:`look_at_many`.

    Args:
        eye: (3,) the camera centre in metres.
        target: (3,) the point it looks at (default the origin).

    Returns:
        (4, 4) the camera-to-world transform.

    Example:
        >>> import numpy as np
        >>> pose = look_at(np.array([0.0, 0.0, 1.0]))  # at the pole, looking down
        >>> bool(np.allclose(pose[:3, 2], [0.0, 0.0, -1.0])), pose[:3, 3].tolist()
        (True, [0.0, 0.0, 1.0])
    """
    return look_at_many(np.asarray(eye, dtype=np.float64)[None], target)[0]


def camera_centres(poses: np.ndarray) -> np.ndarray:
    """Camera centres (n, 3) of poses (n, 4, 4) (their translation column), in metres.

    Example:
        >>> import numpy as np
        >>> camera_centres(look_at_many(np.array([[1.0, 0.0, 0.0]]))).tolist()
        [[1.0, 0.0, 0.0]]
    """
    return np.asarray(poses)[..., :3, 3]


def pixel_directions(intrinsics: Intrinsics) -> np.ndarray:
    """Camera-frame ray directions (height*width, 3) with unit z, row-major over pixels.

    With z = 1 the ray parameter at a hit equals the hit's z-depth, so a ray caster that
    returns the parameter returns the depth image directly.

    Args:
        intrinsics: The camera.

    Returns:
        (height·width, 3) directions ((u − cx)/fx, (v − cy)/fy, 1), pixel (u, v) at row
        v·width + u.

    Example:
        >>> rays = pixel_directions(Intrinsics(4, 2, fx=2.0, fy=2.0, cx=1.5, cy=0.5))
        >>> rays.shape, rays[0].tolist()
        ((8, 3), [-0.75, -0.25, 1.0])
    """
    u, v = np.meshgrid(
        np.arange(intrinsics.width, dtype=np.float64),
        np.arange(intrinsics.height, dtype=np.float64),
    )
    x = (u.ravel() - intrinsics.cx) / intrinsics.fx
    y = (v.ravel() - intrinsics.cy) / intrinsics.fy
    return np.stack([x, y, np.ones_like(x)], axis=1)


def project(
    points: np.ndarray, poses: np.ndarray, intrinsics: Intrinsics
) -> tuple[np.ndarray, np.ndarray]:
    """Project world points into one or many cameras.

    ``points`` is (n, 3); ``poses`` (4, 4) or (m, 4, 4). Returns pixel coordinates (..., n, 2)
    as (u, v) and z-depths (..., n); points behind a camera have depth <= 0.

    Args:
        points: (n, 3) world points in metres.
        poses: (4, 4) or (m, 4, 4) camera-to-world transforms.
        intrinsics: The camera.

    Returns:
        ``(uv, depth)``: (n, 2) or (m, n, 2) pixel coordinates and (n,) or (m, n) z-depths
        in metres.

    Example:
        >>> import numpy as np
        >>> camera = xtion_intrinsics(64, 48)
        >>> uv, depth = project(np.array([[0.0, 0.0, 0.0]]), look_at(np.array([1.0, 0.0, 0.0])),
        ...                     camera)
        >>> uv.tolist(), depth.tolist()  # the target lands on the principal point, 1 m away
        ([[31.5, 23.5]], [1.0])
    """
    points = np.asarray(points, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64)
    rotation = poses[..., :3, :3]
    centre = poses[..., :3, 3]
    # camera coordinates: R^T (p - c)
    relative = points[None, :, :] - centre.reshape(-1, 1, 3)
    cam = np.einsum("mji,mnj->mni", rotation.reshape(-1, 3, 3), relative)
    z = cam[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = intrinsics.fx * cam[..., 0] / z + intrinsics.cx
        v = intrinsics.fy * cam[..., 1] / z + intrinsics.cy
    uv = np.stack([u, v], axis=-1)
    if poses.ndim == 2:
        return uv[0], z[0]
    return uv, z


def back_project(depth: np.ndarray, poses: np.ndarray, intrinsics: Intrinsics) -> np.ndarray:
    """World points (..., height, width, 3) of every pixel of depth images (..., height, width).

    Pixels without depth (0) give the camera centre plus a zero-length ray; select them with
    ``depth > 0``.

    Args:
        depth: (..., height, width) z-depths in metres.
        poses: (..., 4, 4) each image's camera-to-world transform.
        intrinsics: The camera.

    Returns:
        (..., height, width, 3) world points in metres.

    Raises:
        ValueError: The images' size is not the intrinsics'.

    Example:
        >>> import numpy as np
        >>> camera = Intrinsics(3, 3, fx=3.0, fy=3.0, cx=1.0, cy=1.0)
        >>> points = back_project(np.ones((3, 3)), look_at(np.array([1.0, 0.0, 0.0])), camera)
        >>> points.shape, (points[1, 1] + 0.0).tolist()  # the centre pixel sees the origin
        ((3, 3, 3), [0.0, 0.0, 0.0])
    """
    depth = np.asarray(depth, dtype=np.float64)
    poses = np.asarray(poses, dtype=np.float64)
    if depth.shape[-2:] != (intrinsics.height, intrinsics.width):
        raise ValueError(
            f"depth image is {depth.shape[-1]}x{depth.shape[-2]}, intrinsics expect "
            f"{intrinsics.width}x{intrinsics.height}"
        )
    rays = pixel_directions(intrinsics).reshape(intrinsics.height, intrinsics.width, 3)
    cam = rays * depth[..., None]
    rotation = poses[..., :3, :3]
    centre = poses[..., :3, 3]
    # R p for every pixel as one matrix product per image (pixels x 3 times R^T): several
    # times faster than the equivalent einsum, which NumPy runs without BLAS
    pixels = cam.reshape(cam.shape[:-3] + (-1, 3))
    world = np.matmul(pixels, np.swapaxes(rotation, -1, -2))
    world = world.reshape(world.shape[:-2] + cam.shape[-3:])
    return world + centre[..., None, None, :]
