"""A reader of the plain VRML 2.0 that KiCad StepUp exports (trimesh reads no VRML).

Example:
    >>> from rapomdp.data.build.vrml import parse_vrml
    >>> mesh = parse_vrml(b"Shape { geometry IndexedFaceSet { coordIndex [0,1,2,-1] "
    ...                   b"coord Coordinate { point [0 0 0, 1 0 0, 0 1 0] } } }")
    >>> mesh.faces.tolist()
    [[0, 1, 2]]
"""

from __future__ import annotations

import re

import numpy as np
import trimesh

_INDEX_RE = re.compile(rb"coordIndex\s*\[([^\]]*)\]")
_POINT_RE = re.compile(rb"point\s*\[([^\]]*)\]")


def parse_vrml(data: bytes) -> trimesh.Trimesh:
    """The triangles of every ``IndexedFaceSet`` of a VRML 2.0 file with absolute coordinates.

    KiCad StepUp's export has no ``Transform``, ``Inline`` or ``PROTO``; a file with one is
    refused rather than read wrong. Polygons are fan-triangulated; empty sets are skipped.

    Args:
        data: the file's bytes.

    Returns:
        One mesh of every set's triangles (``process=False``: vertices as written, in the
        file's units).

    Raises:
        ValueError: a Transform, Inline or PROTO; a point list whose length is not a multiple
            of 3; a face that names a missing point; or no set with faces.
    """
    if re.search(rb"\b(Transform|Inline|PROTO)\b", data):
        raise ValueError("not a plain IndexedFaceSet export (Transform, Inline or PROTO)")
    vertices: list[np.ndarray] = []
    faces: list[np.ndarray] = []
    offset = 0
    for chunk in data.split(b"IndexedFaceSet")[1:]:
        index_match, point_match = _INDEX_RE.search(chunk), _POINT_RE.search(chunk)
        if index_match is None or point_match is None:
            continue
        points = np.array(point_match.group(1).replace(b",", b" ").split(), dtype=np.float64)
        index = np.array(index_match.group(1).replace(b",", b" ").split(), dtype=np.int64)
        if points.size == 0 or index.size == 0:
            continue  # an empty set (StepUp writes some)
        if points.size % 3:
            raise ValueError("a point list whose length is not a multiple of 3")
        points = points.reshape(-1, 3)
        tris = triangulate(index)
        if len(tris) == 0:
            continue
        if tris.max() >= len(points) or tris.min() < 0:
            raise ValueError("a face refers to a point that does not exist")
        vertices.append(points)
        faces.append(tris + offset)
        offset += len(points)
    if not faces:
        raise ValueError("no IndexedFaceSet with faces")
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False)


def triangulate(index: np.ndarray) -> np.ndarray:
    """Triangles from a ``-1``-separated ``coordIndex`` list, each polygon fanned from its first
    corner (a fast path when every face is already a triangle).

    Args:
        index: (N,) int64, point indices with ``-1`` after each polygon (the last may lack it).

    Returns:
        (F, 3) int64 point indices; polygons of fewer than three corners give none.
    """
    if index.size and index[-1] != -1:
        index = np.append(index, -1)
    if index.size % 4 == 0 and np.all(index[3::4] == -1):
        triangles = index.reshape(-1, 4)[:, :3]
        if not np.any(triangles < 0):
            return triangles
    out = []
    for polygon in np.split(index, np.flatnonzero(index == -1) + 1):
        polygon = polygon[polygon >= 0]
        for k in range(1, len(polygon) - 1):
            out.append((polygon[0], polygon[k], polygon[k + 1]))
    return np.array(out, dtype=np.int64).reshape(-1, 3)
