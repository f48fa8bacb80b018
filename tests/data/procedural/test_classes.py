import numpy as np
import pytest

from rapomdp.data.procedural import PROCEDURAL_CLASSES, generate_model
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints

PAPER_CLASSES = {"bicycle", "motorbike", "teapot", "eyeglasses", "cup", "bottle", "scissors"}


def test_at_least_twelve_classes_including_the_papers() -> None:
    assert len(PROCEDURAL_CLASSES) >= 12
    assert PAPER_CLASSES <= set(PROCEDURAL_CLASSES)


@pytest.mark.parametrize("name", PROCEDURAL_CLASSES)
def test_same_seed_same_mesh_other_seed_or_index_another(name: str) -> None:
    a = generate_model(name, seed=0, index=2)
    np.testing.assert_array_equal(a.vertices, generate_model(name, seed=0, index=2).vertices)
    for other in (generate_model(name, 1, 2), generate_model(name, 0, 3)):
        assert other.vertices.shape != a.vertices.shape or not np.allclose(other.vertices,
                                                                           a.vertices)


@pytest.mark.parametrize("name", PROCEDURAL_CLASSES)
def test_every_class_is_closed_and_renders_without_holes(name: str) -> None:
    mesh = generate_model(name, seed=0, index=0)
    assert mesh.is_watertight
    assert mesh.vertices[:, 2].min() == pytest.approx(0.0)
    centre = (mesh.bounds[0] + mesh.bounds[1]) / 2
    radius = float(np.linalg.norm(mesh.extents)) * 1.6
    poses = look_at_many(viewpoints(24, radius, centre=centre), centre)
    renderer = DepthRenderer(mesh, xtion_intrinsics(64, 48))
    depth, faces = renderer.render_faces(poses)
    assert np.all((depth > 0).sum(axis=(1, 2)) > 0), "a view sees nothing"
    # a hole would let a ray reach the inside of a part: it would hit a back face
    _, directions = renderer.rays(poses)
    hit = faces.ravel() >= 0
    facing = np.einsum("ij,ij->i", mesh.face_normals[faces.ravel()[hit]],
                       directions[hit].astype(np.float64))
    assert np.mean(facing >= 0) < 1e-3


def test_classes_sharing_parts_differ_by_a_part() -> None:
    cup = generate_model("cup", 0, 0)
    mug = generate_model("mug", 0, 0)
    # a mug is a cup-like body plus a handle: it is wider than tall-ish in x than in y
    assert mug.extents[0] > mug.extents[1] * 1.2
    assert cup.extents[0] == pytest.approx(cup.extents[1], rel=0.02)


def test_unknown_class_is_named() -> None:
    with pytest.raises(KeyError, match="unknown procedural class 'lamp'"):
        generate_model("lamp", 0, 0)
