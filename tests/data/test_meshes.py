from pathlib import Path

import numpy as np
import pytest
import trimesh

from rapomdp.data.meshes import (
    MeshLoadError,
    bounding_sphere_radius,
    centroid,
    load_mesh,
    normalise_mesh,
)


def _box() -> trimesh.Trimesh:
    return trimesh.creation.box(extents=(0.2, 0.4, 0.6))


@pytest.mark.parametrize("ext", ["obj", "off", "ply", "stl"])
def test_each_format_loads_the_same_box(tmp_path: Path, ext: str) -> None:
    path = tmp_path / f"box.{ext}"
    _box().export(path)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 12
    np.testing.assert_allclose(mesh.bounds, [[-0.1, -0.2, -0.3], [0.1, 0.2, 0.3]], atol=1e-6)


def test_glb_scene_parts_are_merged_with_their_transforms(tmp_path: Path) -> None:
    scene = trimesh.Scene()
    scene.add_geometry(_box(), node_name="a")
    moved = np.eye(4)
    moved[:3, 3] = [1.0, 0.0, 0.0]
    scene.add_geometry(trimesh.creation.icosphere(subdivisions=1, radius=0.1), node_name="b",
                       transform=moved)
    path = tmp_path / "scene.glb"
    scene.export(path)
    mesh = load_mesh(path)
    assert len(mesh.faces) == 12 + 80
    assert mesh.bounds[1, 0] == pytest.approx(1.1, abs=1e-5)


def test_modelnet_header_fused_with_counts(tmp_path: Path) -> None:
    box = _box()
    body = "\n".join(" ".join(f"{v:.6f}" for v in row) for row in box.vertices)
    faces = "\n".join("3 " + " ".join(str(i) for i in f) for f in box.faces)
    path = tmp_path / "chair_0001.off"
    path.write_text(f"OFF{len(box.vertices)} {len(box.faces)} 0\n{body}\n{faces}\n")
    mesh = load_mesh(path)
    assert len(mesh.vertices) == 8 and len(mesh.faces) == 12
    np.testing.assert_allclose(mesh.bounds[1], [0.1, 0.2, 0.3], atol=1e-6)


def test_empty_unreadable_and_unsupported_files_are_named(tmp_path: Path) -> None:
    empty = tmp_path / "empty.obj"
    empty.write_text("# nothing here\n")
    with pytest.raises(MeshLoadError, match=r"empty\.obj: the file holds no triangles"):
        load_mesh(empty)
    garbage = tmp_path / "broken.ply"
    garbage.write_bytes(b"\x00\x01 definitely not a ply file")
    with pytest.raises(MeshLoadError, match=r"broken\.ply: cannot be read"):
        load_mesh(garbage)
    with pytest.raises(MeshLoadError, match="unsupported mesh format '.txt'"):
        load_mesh(tmp_path / "notes.txt")
    with pytest.raises(MeshLoadError, match="no such file"):
        load_mesh(tmp_path / "missing.stl")


@pytest.mark.parametrize("up", ["z", "y", "-x"])
def test_normalise_stands_the_model_upright_on_the_floor(up: str) -> None:
    # a tall box along the given axis becomes tall along z
    extents = {"z": (0.1, 0.2, 0.9), "y": (0.1, 0.9, 0.2), "-x": (0.9, 0.1, 0.2)}[up]
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation([3.0, -2.0, 5.0])
    out = normalise_mesh(mesh, 0.2, up)
    assert out.vertices[:, 2].min() == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(centroid(out.vertices)[:2], 0.0, atol=1e-12)
    assert bounding_sphere_radius(out.vertices) == pytest.approx(0.2)
    assert np.argmax(out.extents) == 2


def test_normalise_rejects_a_point_mesh() -> None:
    mesh = trimesh.Trimesh(vertices=np.zeros((3, 3)), faces=[[0, 1, 2]], process=False)
    with pytest.raises(MeshLoadError, match="single point"):
        normalise_mesh(mesh, 0.2)
