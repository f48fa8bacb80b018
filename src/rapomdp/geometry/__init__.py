"""Geometry shared by every stage: viewspheres, the pinhole camera and voxel grids."""

from rapomdp.geometry.camera import (
    Intrinsics,
    back_project,
    camera_centres,
    look_at,
    look_at_many,
    pixel_directions,
    project,
    xtion_intrinsics,
)
from rapomdp.geometry.viewsphere import (
    fibonacci_directions,
    geodesic_distance_matrix,
    k_nearest,
    viewpoints,
)
from rapomdp.geometry.voxels import VoxelGrid

__all__ = [
    "Intrinsics",
    "VoxelGrid",
    "back_project",
    "camera_centres",
    "fibonacci_directions",
    "geodesic_distance_matrix",
    "k_nearest",
    "look_at",
    "look_at_many",
    "pixel_directions",
    "project",
    "viewpoints",
    "xtion_intrinsics",
]
