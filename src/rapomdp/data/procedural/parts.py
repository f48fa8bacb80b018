"""Closed mesh parts that the procedural classes are assembled from.

Every part is a closed, outward-facing surface, so a model made of overlapping parts has no
hole through which a camera could see a back face. Parts are in metres, Z up.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import trimesh
from trimesh import creation

Z = np.array([0.0, 0.0, 1.0])


def _outward(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    if mesh.volume < 0:
        mesh.invert()
    return mesh


def _frame(centre: Sequence[float], axis: Sequence[float]) -> np.ndarray:
    """4x4 transform putting the local z axis along ``axis`` at ``centre``."""
    transform = trimesh.geometry.align_vectors(Z, np.asarray(axis, dtype=np.float64))
    transform[:3, 3] = centre
    return transform


def tube(start: Sequence[float], end: Sequence[float], radius: float, sections: int = 10):
    """A solid cylinder from ``start`` to ``end``."""
    return creation.cylinder(radius=radius, segment=[start, end], sections=sections)


def box(extents: Sequence[float], centre: Sequence[float], yaw: float = 0.0,
        pitch: float = 0.0) -> trimesh.Trimesh:
    """An axis-aligned box turned by ``yaw`` about z then ``pitch`` about y."""
    transform = trimesh.transformations.euler_matrix(0.0, pitch, yaw, "sxyz")
    transform[:3, 3] = centre
    return creation.box(extents=extents, transform=transform)


def slab(lower: Sequence[float], upper: Sequence[float]) -> trimesh.Trimesh:
    """An axis-aligned box between two corners (panels, shelves, drawer fronts)."""
    lower, upper = np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64)
    return creation.box(extents=np.abs(upper - lower), transform=trimesh.transformations
                        .translation_matrix((lower + upper) / 2.0))


def ellipsoid(radii: Sequence[float], centre: Sequence[float], subdivisions: int = 2):
    """An ellipsoid with semi-axes ``radii`` along x, y, z."""
    mesh = creation.icosphere(subdivisions=subdivisions, radius=1.0)
    mesh.vertices = mesh.vertices * np.asarray(radii) + np.asarray(centre)
    return mesh


def ring(centre: Sequence[float], axis: Sequence[float], radius: float, thickness: float,
         stretch: Sequence[float] | None = None, sections: int = 28) -> trimesh.Trimesh:
    """A torus (a wheel's tyre, a lens rim, a handle) around ``axis``.

    ``stretch`` (3,) scales the ring along world axes about its centre (an elliptical rim).
    """
    mesh = creation.torus(radius, thickness, major_sections=sections, minor_sections=8)
    mesh.apply_transform(_frame((0.0, 0.0, 0.0), axis))
    if stretch is not None:
        mesh.vertices = mesh.vertices * np.asarray(stretch, dtype=np.float64)
    mesh.apply_translation(centre)
    return mesh


def disc(centre: Sequence[float], axis: Sequence[float], radius: float, width: float,
         sections: int = 24) -> trimesh.Trimesh:
    """A short solid cylinder (a hub, a solid wheel, a lens) centred at ``centre``."""
    axis = np.asarray(axis, dtype=np.float64)
    axis = axis / np.linalg.norm(axis)
    half = axis * width / 2.0
    return creation.cylinder(radius=radius, segment=[centre - half, centre + half],
                             sections=sections)


def revolved(profile: Sequence[Sequence[float]], centre: Sequence[float] = (0.0, 0.0, 0.0),
             sections: int = 28) -> trimesh.Trimesh:
    """A solid of revolution about the vertical axis from a (radius, height) profile.

    The profile must start and end on the axis (radius 0), which closes the surface.
    """
    profile = np.asarray(profile, dtype=np.float64)
    if profile[0, 0] != 0.0 or profile[-1, 0] != 0.0:
        raise ValueError("a revolved profile must start and end on the axis")
    mesh = creation.revolve(profile, sections=sections)
    mesh.apply_translation(centre)
    return _outward(mesh)


def vessel(outer: Sequence[Sequence[float]], wall: float, floor: float,
           centre: Sequence[float] = (0.0, 0.0, 0.0), sections: int = 28) -> trimesh.Trimesh:
    """An open vessel (cup, mug, vase) from its outer (radius, height) profile, bottom to rim.

    The inner wall follows the outer one ``wall`` inside it, down to a floor ``floor`` thick, so
    the cavity is seen from above.
    """
    outer = np.asarray(outer, dtype=np.float64)
    inner = outer[::-1].copy()
    inner[:, 0] = np.maximum(inner[:, 0] - wall, wall * 0.5)
    inner[-1, 1] = max(inner[-1, 1], floor)
    inner = inner[inner[:, 1] >= floor]
    profile = np.vstack([[0.0, outer[0, 1]], outer, inner, [[0.0, inner[-1, 1]]]])
    return revolved(profile, centre, sections)


def spoked_wheel(centre: Sequence[float], axis: Sequence[float], radius: float, tyre: float,
                 spokes: int, spoke_radius: float, hub_radius: float,
                 hub_width: float) -> list[trimesh.Trimesh]:
    """A tyre, a hub and straight spokes: the wheel bicycles and wheelchairs share."""
    centre = np.asarray(centre, dtype=np.float64)
    axis = np.asarray(axis, dtype=np.float64) / np.linalg.norm(axis)
    frame = _frame(centre, axis)
    parts = [ring(centre, axis, radius, tyre), disc(centre, axis, hub_radius, hub_width, 12)]
    angles = np.arange(spokes) * 2.0 * np.pi / max(spokes, 1)
    rim = radius - tyre * 0.5
    for angle in angles:
        tip = frame[:3, :3] @ np.array([np.cos(angle) * rim, np.sin(angle) * rim, 0.0]) + centre
        parts.append(tube(centre, tip, spoke_radius, sections=5))
    return parts


def solid_wheel(centre: Sequence[float], axis: Sequence[float], radius: float, tyre: float,
                width: float) -> list[trimesh.Trimesh]:
    """A thick tyre around a solid rim: the wheel motorbikes and cars share."""
    return [ring(centre, axis, radius, tyre), disc(centre, axis, radius - tyre * 0.6, width)]


def assemble(parts: Sequence[trimesh.Trimesh]) -> trimesh.Trimesh:
    """One mesh from closed parts (overlaps are fine: their hidden faces are never seen)."""
    mesh = trimesh.util.concatenate(list(parts))
    return trimesh.Trimesh(vertices=mesh.vertices, faces=mesh.faces, process=False)
