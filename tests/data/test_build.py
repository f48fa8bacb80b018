"""The dataset builders (``rapomdp.data.build``) on small fixtures the tests make: a few tiny
VRML models in the layout of an unpacked ``kicad-packages3d`` (and the same as a ``.deb``), and
the mesh set at two models a class."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import trimesh

from rapomdp.data.build import BUILDERS, DatasetBuildError, build
from rapomdp.data.build.common import BUILT_MARKER, refuse_held_back
from rapomdp.data.build.mesh_set import SHAPES, build_mesh_set
from rapomdp.data.build.real_cad import (
    COPYRIGHT,
    FIRST_SET,
    MODELS_DIR,
    PACKAGE,
    SECOND_SET,
    build_real_cad,
    check_deb,
    family,
    fetch_deb,
    near_duplicate,
    select,
    signature,
)
from rapomdp.data.build.vrml import parse_vrml, triangulate
from rapomdp.data.layouts import discover_models

COPYRIGHT_TEXT = """Format: https://www.debian.org/doc/packaging-manuals/copyright-format/1.0/

Files: *
Copyright: KiCad
License: CC-BY-SA-4.0-with-exception
 text

Files: Capacitor_THT.3dshapes/*
Copyright: someone
License: GPL-3+
 text
"""


def vrml(mesh: trimesh.Trimesh) -> bytes:
    """``mesh`` as KiCad StepUp writes it: one IndexedFaceSet, absolute coordinates."""
    points = ", ".join(" ".join(f"{v:.6f}" for v in p) for p in mesh.vertices)
    index = ", ".join(f"{a},{b},{c},-1" for a, b, c in mesh.faces)
    return (f"#VRML V2.0 utf8\nShape {{ geometry IndexedFaceSet {{ coordIndex [{index}] "
            f"coord Coordinate {{ point [{points}] }} }} }}\n").encode()


def box(extents: tuple[float, float, float]) -> trimesh.Trimesh:
    """A box of 192 triangles (over the 64 a model needs)."""
    return trimesh.creation.box(extents).subdivide().subdivide()


def kicad_tree(root: Path, folders: dict[str, str]) -> Path:
    """An unpacked kicad-packages3d with, in every folder: three boxes of distinct proportions,
    one repeat of the first under another name, one flat plate and one unreadable file."""
    (root / COPYRIGHT).parent.mkdir(parents=True)
    (root / COPYRIGHT).write_text(COPYRIGHT_TEXT)
    for k, folder in enumerate(folders):
        target = root / MODELS_DIR / f"{folder}.3dshapes"
        target.mkdir(parents=True)
        for i, extents in enumerate([(1.0, 1.0, 1.0), (2.0, 1.0, 0.5), (1.0, 3.0 + k, 0.7)]):
            (target / f"M_{i}_D{i}.0mm.wrl").write_bytes(vrml(box(extents)))
        (target / "M_9_copy.wrl").write_bytes(vrml(box((1.0, 1.0, 1.0))))
        (target / "Flat_plate.wrl").write_bytes(vrml(box((1.0, 1.0, 0.001))))
        (target / "Odd_transform.wrl").write_bytes(b"#VRML V2.0 utf8\nTransform { }\n")
    return root


def test_vrml_is_read_as_written_and_a_transform_is_refused() -> None:
    mesh = box((1.0, 2.0, 3.0))
    read = parse_vrml(vrml(mesh))
    assert read.faces.tolist() == mesh.faces.tolist()
    np.testing.assert_allclose(read.vertices, mesh.vertices, atol=1e-6)
    assert triangulate(np.array([0, 1, 2, 3, -1, 4, 5, 6])).tolist() == [[0, 1, 2], [0, 2, 3],
                                                                        [4, 5, 6]]
    with pytest.raises(ValueError, match="Transform, Inline or PROTO"):
        parse_vrml(b"Transform { children [ IndexedFaceSet { } ] }")
    with pytest.raises(ValueError, match="does not exist"):
        parse_vrml(b"IndexedFaceSet { coordIndex [0,1,5,-1] coord Coordinate { point "
                   b"[0 0 0, 1 0 0, 0 1 0] } }")


def test_the_rules_name_families_spot_repeats_and_spread_the_picks() -> None:
    assert family("CP_Radial_D10.0mm_P5.00mm") == "CP_Radial"
    assert family("DIP-8_W7.62mm") == "DIP-8"
    assert family("Relay_SPDT_Finder_36.11") == "Relay_SPDT"
    a, b = signature(box((1, 2, 3))), signature(box((2, 4, 6)))
    assert near_duplicate(a, b)  # the same shape at twice the size
    assert not near_duplicate(a, signature(box((1, 2, 4))))
    signatures = {f"A_{i}": signature(box((1, 1 + i, 1))) for i in range(4)}
    signatures["B_0"] = signature(box((1, 1, 5)))
    picked = select(signatures, 2)
    assert len(picked) == 2 and "B_0" in picked  # both families before any twice
    assert select(signatures, 0) == sorted(signatures)


def test_real_cad_builds_every_class_from_an_unpacked_package(tmp_path: Path) -> None:
    source = kicad_tree(tmp_path / "pkg", FIRST_SET)
    out = tmp_path / "meshes"
    lines: list[str] = []
    result = build_real_cad(out, source=source, max_per_class=2, progress=lines.append)
    layout, found = discover_models(out)
    assert layout == "generic"
    assert sorted(found) == sorted(FIRST_SET.values())
    assert all(len(files) == 2 and all(f.suffix == ".ply" for f in files)
               for files in found.values())
    assert len(lines) == 12 and lines[0] == "resistor: 2 of 6"
    info = json.loads((out / "SOURCE.json").read_text())
    capacitor = info["classes"]["capacitor"]
    assert (capacitor["files"], capacitor["candidates"], len(capacitor["kept"])) == (6, 3, 2)
    assert capacitor["duplicates"] == ["M_9_copy"]
    assert [d.split(" ")[0] for d in capacitor["degenerate"]] == ["Flat_plate"]
    assert [u.split(" ")[0] for u in capacitor["unreadable"]] == ["Odd_transform"]
    assert {m["licence"] for m in capacitor["kept"]} == {"GPL-3+"}
    assert {m["licence"] for m in info["classes"]["resistor"]["kept"]} == {
        "CC-BY-SA-4.0-with-exception"}
    kept = capacitor["kept"][0]
    assert trimesh.load(out / kept["file"]).faces.shape == (kept["faces"], 3) == (192, 3)
    assert "| total |  | 72 | 12 | 12 | 12 | 36 | 24 |" in (out / "SOURCE.md").read_text()
    assert "capacitor" in result.summary() and "classes under 11 models" in result.summary()


def test_a_rebuild_replaces_the_folder_whole_with_the_same_files(tmp_path: Path) -> None:
    source = kicad_tree(tmp_path / "pkg", SECOND_SET)
    out = tmp_path / "meshes"
    build_real_cad(out, which="second", source=source, max_per_class=3)
    first = {p.relative_to(out): hashlib.sha256(p.read_bytes()).hexdigest()
             for p in out.rglob("*.ply")}
    (out / "stray.txt").write_text("left by hand")
    build_real_cad(out, which="second", source=source, max_per_class=3)
    again = {p.relative_to(out): hashlib.sha256(p.read_bytes()).hexdigest()
             for p in out.rglob("*.ply")}
    assert again == first and len(first) == 36
    assert not (out / "stray.txt").exists()
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []


@pytest.mark.skipif(shutil.which("dpkg-deb") is None, reason="dpkg-deb is Debian's")
def test_real_cad_from_a_deb_records_the_package(tmp_path: Path) -> None:
    tree = kicad_tree(tmp_path / "tree", FIRST_SET)
    (tree / "DEBIAN").mkdir()
    (tree / "DEBIAN" / "control").write_text(
        f"Package: {PACKAGE}\nVersion: 0.1-test\nArchitecture: all\nMaintainer: t <t@t>\n"
        "Homepage: https://example.invalid/kicad\nDescription: a fixture\n")
    deb = tmp_path / f"{PACKAGE}_0.1-test_all.deb"
    subprocess.run(["dpkg-deb", "--build", "--root-owner-group", str(tree), str(deb)],
                   check=True, capture_output=True)
    out = tmp_path / "meshes"
    result = build_real_cad(out, deb=deb, cache=tmp_path / "cache", max_per_class=1)
    assert result.info["version"] == "0.1-test"
    assert result.info["deb_sha256"] == hashlib.sha256(deb.read_bytes()).hexdigest()
    assert sum(1 for _ in out.rglob("*.ply")) == 12
    assert len(list((tmp_path / "cache").glob("*/.complete"))) == 1
    other = tmp_path / "other_1_all.deb"
    (tree / "DEBIAN" / "control").write_text(
        "Package: other\nVersion: 1\nArchitecture: all\nMaintainer: t <t@t>\nDescription: x\n")
    subprocess.run(["dpkg-deb", "--build", "--root-owner-group", str(tree), str(other)],
                   check=True, capture_output=True)
    with pytest.raises(DatasetBuildError, match="is the package 'other', not kicad-packages3d"):
        check_deb(other)


def test_held_back_sources_are_refused_by_name_before_anything_is_read(tmp_path: Path) -> None:
    with pytest.raises(DatasetBuildError, match="package 'sweethome3d-furniture' is held back"):
        fetch_deb(tmp_path / "cache", "sweethome3d-furniture")
    assert list((tmp_path).iterdir()) == []  # no cache made, nothing downloaded
    held = tmp_path / "sweethome3d-furniture_1_all.deb"
    held.write_bytes(b"not even a package")
    with pytest.raises(DatasetBuildError, match="--deb file 'sweethome3d-furniture_1_all.deb'"):
        build_real_cad(tmp_path / "out", deb=held, cache=tmp_path / "cache")
    with pytest.raises(DatasetBuildError, match="--source folder 'SweetHome3D-models' is held"):
        build_real_cad(tmp_path / "out", source=tmp_path / "SweetHome3D-models")
    assert not (tmp_path / "out").exists()
    refuse_held_back(["kicad-packages3d", "flightgear-data-models"], "package")


def test_bad_requests_are_refused_with_what_to_do(tmp_path: Path) -> None:
    with pytest.raises(DatasetBuildError, match="--set must be one of first, second"):
        build_real_cad(tmp_path / "out", which="third", source=tmp_path)
    with pytest.raises(DatasetBuildError, match="--max-per-class must be 0"):
        build_real_cad(tmp_path / "out", max_per_class=-1, source=tmp_path)
    with pytest.raises(DatasetBuildError, match="not an unpacked kicad-packages3d"):
        build_real_cad(tmp_path / "out", source=tmp_path)
    with pytest.raises(DatasetBuildError, match="no dataset builder 'shapenet'"):
        build("shapenet", tmp_path / "out")
    with pytest.raises(DatasetBuildError, match="mesh-set does not take --source, --set"):
        build("mesh-set", tmp_path / "out", which="first", source=tmp_path, seed=None)
    with pytest.raises(DatasetBuildError, match="--models must be 1 or more"):
        build_mesh_set(tmp_path / "out", models_per_class=0)
    assert not (tmp_path / "out").exists()


def test_the_mesh_set_writes_every_class_and_a_model_does_not_depend_on_the_count(
        tmp_path: Path) -> None:
    assert build("mesh-set", tmp_path / "two", models_per_class=2, seed=7).startswith(
        "wrote 22 meshes of 11 classes")
    layout, found = discover_models(tmp_path / "two")
    assert layout == "generic" and sorted(found) == sorted(SHAPES)
    assert all([f.name for f in files] == [f"{c}_00.stl", f"{c}_01.stl"]
               for c, files in found.items())
    build_mesh_set(tmp_path / "three", models_per_class=3, seed=7)
    for name in SHAPES:
        two = (tmp_path / "two" / name / f"{name}_01.stl").read_bytes()
        assert two == (tmp_path / "three" / name / f"{name}_01.stl").read_bytes()
        mesh = trimesh.load(tmp_path / "three" / name / f"{name}_02.stl")
        assert len(mesh.faces) > 20 and mesh.extents.min() > 0
    other_seed = build_mesh_set(tmp_path / "seed8", models_per_class=1, seed=8)
    assert other_seed == dict.fromkeys(SHAPES, 1)
    assert ((tmp_path / "seed8" / "lamp" / "lamp_00.stl").read_bytes()
            != (tmp_path / "two" / "lamp" / "lamp_00.stl").read_bytes())


def test_every_builder_says_what_it_needs_and_how_long() -> None:
    assert set(BUILDERS) == {"real-cad", "mesh-set"}
    assert "apt-get" in BUILDERS["real-cad"].needs and "--source" in BUILDERS["real-cad"].needs
    assert all(b.duration and b.config.startswith("configs/") for b in BUILDERS.values())


def test_a_folder_a_builder_did_not_make_is_never_replaced(tmp_path: Path) -> None:
    """--out naming a user's own folder is refused before any work, and the folder is intact;
    a new, an empty or a built folder is taken."""
    own = tmp_path / "photos"
    own.mkdir()
    (own / "holiday.jpg").write_bytes(b"mine")
    source = kicad_tree(tmp_path / "pkg", SECOND_SET)
    with pytest.raises(DatasetBuildError, match="photos exists and was not made by"):
        build_real_cad(own, which="second", source=source, max_per_class=3)
    with pytest.raises(DatasetBuildError, match="name a new or empty folder"):
        build_mesh_set(own, models_per_class=1)
    assert [p.name for p in own.iterdir()] == ["holiday.jpg"]
    assert (own / "holiday.jpg").read_bytes() == b"mine"
    empty = tmp_path / "empty"
    empty.mkdir()
    build_mesh_set(empty, models_per_class=1)
    assert (empty / BUILT_MARKER).is_file()
    build_mesh_set(empty, models_per_class=1)  # a built folder is rebuilt
    assert (empty / BUILT_MARKER).is_file()
