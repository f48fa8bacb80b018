import numpy as np
import pytest
import trimesh

from rapomdp.data.meshes import normalise_mesh
from rapomdp.data.preview import preview_pose
from rapomdp.data.procedural import CLASSES, FAMILIES, PROCEDURAL_CLASSES, generate_model
from rapomdp.data.procedural.classes import build_parts, generate_parts, model_rng
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints

PAPER_CLASSES = {"bicycle", "motorbike", "teapot", "eyeglasses", "cup", "bottle", "scissors"}
CUED = [name for name, c in CLASSES.items() if c.seen_from is not None]


def test_thirty_classes_in_families_including_the_papers() -> None:
    assert len(PROCEDURAL_CLASSES) >= 30
    assert PAPER_CLASSES <= set(PROCEDURAL_CLASSES)
    assert sum(len(v) for v in FAMILIES.values()) == len(PROCEDURAL_CLASSES)
    assert all(len(members) >= 2 for members in FAMILIES.values())
    assert FAMILIES["cups"] == ("cup", "mug", "jug", "beaker")
    assert len(CUED) >= 10


@pytest.mark.parametrize("name", PROCEDURAL_CLASSES)
def test_same_seed_same_mesh_other_seed_or_index_another(name: str) -> None:
    a = generate_model(name, seed=0, index=2)
    np.testing.assert_array_equal(a.vertices, generate_model(name, seed=0, index=2).vertices)
    np.testing.assert_array_equal(a.faces, generate_model(name, seed=0, index=2).faces)
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


@pytest.mark.parametrize("family", [f for f in FAMILIES if f != "small"])
def test_classes_of_a_family_share_the_body_and_differ_by_their_parts(family: str) -> None:
    members = FAMILIES[family]
    built = {name: build_parts(name, np.random.default_rng(7)) for name in members}
    first = built[members[0]]
    body = [k for k in first if k.startswith("body/")]
    assert body, "a family has a shared body"
    for name in members[1:]:
        for key in body:
            np.testing.assert_array_equal(built[name][key].vertices, first[key].vertices)
            np.testing.assert_array_equal(built[name][key].faces, first[key].faces)
    own = {name: sorted(k for k in parts if not k.startswith("body/"))
           for name, parts in built.items()}
    meshes = {name: trimesh.util.concatenate([built[name][k] for k in own[name]])
              if own[name] else None for name in members}
    for i, a in enumerate(members):
        for b in members[i + 1:]:
            same_parts = own[a] == own[b] and (
                meshes[a] is None or (meshes[a].vertices.shape == meshes[b].vertices.shape
                                      and np.allclose(meshes[a].vertices, meshes[b].vertices)))
            assert not same_parts, f"{a} and {b} are built alike"


def test_models_of_a_class_vary_in_proportions() -> None:
    for name in ("cabinet", "mug", "car", "chair"):
        extents = np.array([generate_model(name, 0, i).extents for i in range(6)])
        ratios = extents / extents[:, 2:3]
        assert np.ptp(ratios, axis=0).max() > 0.2, name


def _cue_pixels(name: str, index: int, elevation_deg: float, azimuth_deg: float) -> tuple[int, int]:
    """Pixels of a class's cue part and of the whole model, seen from a direction."""
    parts = generate_parts(name, 0, index)
    keys = list(parts)
    sizes = np.array([len(parts[k].faces) for k in keys])
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    mesh = normalise_mesh(trimesh.util.concatenate([parts[k] for k in keys]), 0.2)
    cue = keys.index(CLASSES[name].cue)
    centre = (mesh.bounds[0] + mesh.bounds[1]) / 2
    renderer = DepthRenderer(mesh, xtion_intrinsics(80, 60))
    _, faces = renderer.render_faces(preview_pose(centre, 0.6, elevation_deg, azimuth_deg))
    on_cue = (faces >= offsets[cue]) & (faces < offsets[cue + 1])
    return int(on_cue.sum()), int((faces >= 0).sum())


@pytest.mark.parametrize("name", CUED)
def test_a_cue_is_seen_from_its_side_and_hidden_from_the_opposite(name: str) -> None:
    elevation, azimuth = CLASSES[name].seen_from
    for index in range(3):
        seen, total = _cue_pixels(name, index, elevation, azimuth)
        hidden, _ = _cue_pixels(name, index, elevation, azimuth + 180.0)
        assert seen >= 0.03 * total, (name, index, seen, total)
        assert hidden <= 0.1 * seen, (name, index, hidden, seen)


def test_a_mug_seen_from_behind_its_handle_looks_like_its_body() -> None:
    seen, _ = _cue_pixels("mug", 0, 0.0, 0.0)
    hidden, _ = _cue_pixels("mug", 0, 0.0, 180.0)
    assert seen > 20 and hidden == 0


def test_unknown_class_and_negative_index_are_named() -> None:
    with pytest.raises(KeyError, match="unknown procedural class 'lamp'"):
        generate_model("lamp", 0, 0)
    with pytest.raises(ValueError, match="non-negative"):
        model_rng("cup", 0, -1)
