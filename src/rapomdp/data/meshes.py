"""Mesh loading (OBJ, OFF, PLY, STL, GLB/GLTF) and normalisation to the project's frame.

After :func:`normalise_mesh` a model stands upright on the floor (z = 0), its bounding box is
centred on the z axis and its bounding sphere about the bounding-box centre (the *centroid*)
has the configured radius, so all classes have the same size, as in the paper.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import trimesh

from rapomdp.data.layouts import MESH_EXTENSIONS

# ModelNet writes some headers as "OFF490 518 0": the keyword runs into the counts.
_FUSED_OFF_HEADER = re.compile(rb"^\s*OFF(?=[\s\d-])(?!\s*\n)")

UP_AXES = {
    "x": np.array([1.0, 0.0, 0.0]),
    "y": np.array([0.0, 1.0, 0.0]),
    "z": np.array([0.0, 0.0, 1.0]),
    "-x": np.array([-1.0, 0.0, 0.0]),
    "-y": np.array([0.0, -1.0, 0.0]),
    "-z": np.array([0.0, 0.0, -1.0]),
}


class MeshLoadError(ValueError):
    """A mesh file cannot be used: unreadable, unsupported or empty (the file is named)."""


def _read_off_bytes(path: Path) -> trimesh.Trimesh:
    data = path.read_bytes()
    first, _, rest = data.partition(b"\n")
    if _FUSED_OFF_HEADER.match(first) and first.strip() != b"OFF":
        counts = first.strip()[3:]
        data = b"OFF\n" + counts + b"\n" + rest
    return trimesh.load(io.BytesIO(data), file_type="off", force="mesh", process=False)


#: The largest mesh file :func:`load_mesh` reads by default (``limits.mesh_file_mb``).
DEFAULT_MAX_MESH_BYTES = 256 * 10**6


def load_mesh(path: str | Path, max_bytes: int = DEFAULT_MAX_MESH_BYTES) -> trimesh.Trimesh:
    """One triangle mesh from a file; a multi-part scene is merged with its transforms. A file
    larger than ``max_bytes`` is refused before it is read."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in MESH_EXTENSIONS:
        raise MeshLoadError(
            f"{path}: unsupported mesh format '{suffix}' (use {', '.join(MESH_EXTENSIONS)})"
        )
    if not path.is_file():
        raise MeshLoadError(f"{path}: no such file")
    size = path.stat().st_size
    if size > max_bytes:
        raise MeshLoadError(f"{path}: {size / 1e6:.0f} MB, over the mesh file cap of "
                            f"{max_bytes / 1e6:.0f} MB (limits.mesh_file_mb); not read")
    try:
        if suffix == ".off":
            mesh = _read_off_bytes(path)
        else:
            loaded = trimesh.load(path, force="scene", process=False)
            mesh = loaded.to_mesh() if isinstance(loaded, trimesh.Scene) else loaded
    except MeshLoadError:
        raise
    except Exception as exc:  # trimesh raises many types for a broken file
        raise MeshLoadError(f"{path}: cannot be read as a mesh ({exc})") from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshLoadError(f"{path}: the file holds no triangles")
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if not np.all(np.isfinite(vertices)):
        raise MeshLoadError(f"{path}: the mesh has non-finite vertex coordinates")
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if faces.max() >= len(vertices) or faces.min() < 0:
        raise MeshLoadError(f"{path}: a face refers to a vertex that does not exist")
    loaded = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
    check_surface(loaded, path)
    return loaded


#: A face is degenerate when its area is below this fraction of the squared bounding-box
#: diagonal (a sliver no ray hits at any resolution the project renders).
DEGENERATE_AREA_FRACTION = 1e-12


def check_surface(mesh: trimesh.Trimesh, source: str | Path) -> None:
    """Refuse a mesh with no surface to see: every face of zero area (collinear or repeated
    vertices), which would render empty from every view and still reach the tables."""
    vertices = np.asarray(mesh.vertices)
    diagonal_sq = float(np.sum(np.ptp(vertices, axis=0) ** 2)) if len(vertices) else 0.0
    areas = np.asarray(mesh.area_faces)
    if diagonal_sq <= 0 or not np.any(areas > DEGENERATE_AREA_FRACTION * diagonal_sq):
        raise MeshLoadError(f"{source}: every face of the mesh is degenerate (zero area): "
                            "nothing to render")


def up_rotation(up_axis: str) -> np.ndarray:
    """The 3x3 rotation taking the mesh's ``up_axis`` to +Z (a right-handed turn)."""
    if up_axis not in UP_AXES:
        raise ValueError(f"unknown up axis '{up_axis}'; use one of {', '.join(UP_AXES)}")
    return trimesh.geometry.align_vectors(UP_AXES[up_axis], UP_AXES["z"])[:3, :3]


def bounding_sphere_radius(vertices: np.ndarray) -> float:
    """Radius of the sphere about the bounding-box centre that holds every vertex."""
    centre = (vertices.min(axis=0) + vertices.max(axis=0)) / 2.0
    return float(np.linalg.norm(vertices - centre, axis=1).max())


def normalise_mesh(mesh: trimesh.Trimesh, radius_m: float, up_axis: str = "z") -> trimesh.Trimesh:
    """Upright on the floor, centred in x and y, bounding-sphere radius ``radius_m``."""
    if radius_m <= 0:
        raise ValueError(f"normalisation radius must be positive, got {radius_m} m")
    vertices = np.asarray(mesh.vertices, dtype=np.float64) @ up_rotation(up_axis).T
    lower, upper = vertices.min(axis=0), vertices.max(axis=0)
    centre = (lower + upper) / 2.0
    vertices = vertices - centre
    radius = bounding_sphere_radius(vertices)
    if radius <= 0:
        raise MeshLoadError("the mesh is a single point: it has no size to normalise")
    vertices *= radius_m / radius
    vertices[:, 2] -= vertices[:, 2].min()
    return trimesh.Trimesh(vertices=vertices, faces=np.asarray(mesh.faces), process=False)


def centroid(vertices: np.ndarray) -> np.ndarray:
    """The object's centroid: its bounding-box centre (the viewspheres' centre)."""
    vertices = np.asarray(vertices)
    return (vertices.min(axis=0) + vertices.max(axis=0)) / 2.0
