"""Shared fixtures: small procedural models rendered directly."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.data.meshes import normalise_mesh
from rapomdp.data.procedural import generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics

RADIUS_M = 0.2


@pytest.fixture(scope="session")
def intrinsics():
    return xtion_intrinsics(160, 120)


@pytest.fixture(scope="session")
def render_model(intrinsics):
    """``f(class_name, eyes_m)``: depth images (n, H, W) of a normalised procedural model seen
    from ``eyes_m`` (n, 3), relative to its centroid."""

    def render(class_name: str, eyes_m: np.ndarray, index: int = 0) -> np.ndarray:
        mesh = normalise_mesh(generate_model(class_name, 0, index), RADIUS_M, "z")
        centroid = np.array([0.0, 0.0, float(np.ptp(mesh.vertices[:, 2])) / 2.0])
        poses = look_at_many(centroid + np.asarray(eyes_m, dtype=np.float64), centroid)
        return DepthRenderer(mesh, intrinsics).render(poses)

    return render
