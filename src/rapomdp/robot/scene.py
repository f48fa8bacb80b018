"""The scene: where the arm stands, where the object's centroid is, how the camera is mounted.

All poses are 4x4 homogeneous transforms. The world frame is the object's (Z up, floor z = 0);
the robot's own frame is its base link ``panda_link0``; the camera frame follows the project's
OpenCV convention (z = optical axis, see :mod:`rapomdp.geometry.camera`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rapomdp.geometry.viewsphere import fibonacci_directions


def rpy_matrix(rpy_rad: np.ndarray | tuple[float, ...]) -> np.ndarray:
    """Rotation (3, 3) from roll, pitch, yaw about fixed x, y, z (URDF: Rz(y) Ry(p) Rx(r))."""
    roll, pitch, yaw = np.asarray(rpy_rad, dtype=np.float64)
    cr, sr, cp, sp, cy, sy = (np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch),
                              np.cos(yaw), np.sin(yaw))
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


def transform(
    xyz_m: np.ndarray | tuple[float, ...], rpy_rad: np.ndarray | tuple[float, ...] = (0, 0, 0)
) -> np.ndarray:
    """A 4x4 transform from a translation and roll-pitch-yaw (see :func:`rpy_matrix`)."""
    pose = np.eye(4)
    pose[:3, :3] = rpy_matrix(rpy_rad)
    pose[:3, 3] = np.asarray(xyz_m, dtype=np.float64)
    return pose


def invert(pose: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (..., 4, 4)."""
    pose = np.asarray(pose, dtype=np.float64)
    rotation_t = np.swapaxes(pose[..., :3, :3], -1, -2)
    inverse = np.zeros_like(pose)
    inverse[..., :3, :3] = rotation_t
    inverse[..., :3, 3] = -np.einsum("...ij,...j->...i", rotation_t, pose[..., :3, 3])
    inverse[..., 3, 3] = 1.0
    return inverse


@dataclass(frozen=True)
class Scene:
    """The arm's base pose and the camera mount, both fixed; the object centroid in the world.

    ``base_world`` maps robot-base coordinates to the world; ``mount`` maps camera coordinates
    to the flange (``panda_link8``) frame.

    Attributes:
        base_world: (4, 4) robot base to world.
        centroid_world: (3,) the object's centroid in the world, metres.
        mount: (4, 4) camera to flange.

    Example:
        >>> from rapomdp.config import Config
        >>> scene = Scene.from_config(Config().robot)
        >>> scene.centroid_world.tolist(), scene.viewpoints_world(4, radius_m=0.5).shape
        ([0.0, 0.0, 0.2], (4, 3))
    """

    base_world: np.ndarray
    centroid_world: np.ndarray
    mount: np.ndarray

    @classmethod
    def from_config(cls, robot: object) -> Scene:
        """The scene of a :class:`~rapomdp.config.RobotConfig`."""
        base = transform(robot.base_xyz_m, (0.0, 0.0, np.radians(robot.base_yaw_deg)))
        mount = transform(robot.camera_mount_xyz_m, np.radians(robot.camera_mount_rpy_deg))
        return cls(base, np.asarray(robot.centroid_m, dtype=np.float64), mount)

    @property
    def centroid_base(self) -> np.ndarray:
        """The object's centroid in the robot's base frame (where it sits in the workspace)."""
        return (invert(self.base_world) @ np.append(self.centroid_world, 1.0))[:3]

    def viewpoints_world(self, count: int, radius_m: float) -> np.ndarray:
        """The test viewpoints X_rho (count, 3): Fibonacci points on the upper hemisphere.

        Index i is the same viewpoint as index i of every other stage, which all take their
        directions from :func:`~rapomdp.geometry.viewsphere.fibonacci_directions`.
        """
        if radius_m <= 0:
            raise ValueError(f"viewsphere radius must be positive, got {radius_m} m")
        return self.centroid_world + radius_m * fibonacci_directions(count, hemisphere=True)
