import json
from pathlib import Path

import pytest
import trimesh

from rapomdp.config import DatasetConfig
from rapomdp.data.layouts import (
    DatasetLayoutError,
    detect_layout,
    discover_models,
    folder_models,
)


def _write(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    trimesh.creation.box().export(path)


def test_generic_layout(tmp_path: Path) -> None:
    for name in ("a.obj", "b.stl", "c.ply"):
        _write(tmp_path / "cup" / name)
    _write(tmp_path / "mug" / "x.off")
    (tmp_path / "mug" / "readme.txt").write_text("not a mesh")
    layout, found = discover_models(tmp_path)
    assert layout == "generic"
    assert {k: [p.name for p in v] for k, v in found.items()} == {
        "cup": ["a.obj", "b.stl", "c.ply"], "mug": ["x.off"]}


def test_objectnet3d_layout(tmp_path: Path) -> None:
    for c in ("bicycle", "teapot"):
        for i in (1, 2):
            _write(tmp_path / "CAD" / "off" / c / f"{i:02d}.off")
    layout, found = discover_models(tmp_path)
    assert layout == "objectnet3d"
    assert [p.name for p in found["teapot"]] == ["01.off", "02.off"]
    assert discover_models(tmp_path / "CAD" / "off", "objectnet3d")[1].keys() == found.keys()


def test_modelnet_layout_pools_train_and_test(tmp_path: Path) -> None:
    _write(tmp_path / "chair" / "train" / "chair_0001.off")
    _write(tmp_path / "chair" / "test" / "chair_0900.off")
    layout, found = discover_models(tmp_path)
    assert layout == "modelnet"
    assert [p.name for p in found["chair"]] == ["chair_0001.off", "chair_0900.off"]


def test_shapenet_layout_names_classes_from_taxonomy(tmp_path: Path) -> None:
    for model in ("m1", "m2"):
        _write(tmp_path / "02876657" / model / "models" / "model_normalized.obj")
    (tmp_path / "taxonomy.json").write_text(
        json.dumps([{"synsetId": "02876657", "name": "bottle,wine bottle", "children": []}]))
    layout, found = discover_models(tmp_path)
    assert layout == "shapenet"
    assert list(found) == ["bottle"] and len(found["bottle"]) == 2
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"02876657": "flask"}))
    assert list(discover_models(tmp_path, "shapenet", mapping)[1]) == ["flask"]
    with pytest.raises(DatasetLayoutError, match="synset map not found"):
        discover_models(tmp_path, "shapenet", tmp_path / "nope.json")


def test_missing_folders_and_empty_layouts_are_named(tmp_path: Path) -> None:
    with pytest.raises(DatasetLayoutError, match="dataset folder not found"):
        discover_models(tmp_path / "nowhere")
    (tmp_path / "empty_class").mkdir()
    with pytest.raises(DatasetLayoutError, match="no mesh files found in the 'generic' layout"):
        discover_models(tmp_path)
    assert detect_layout(tmp_path) == "generic"


def test_folder_models_reads_the_dataset_section_alone(tmp_path: Path) -> None:
    for c in ("chair", "desk", "lamp"):
        _write(tmp_path / c / "train" / f"{c}_0001.off")
    _write(tmp_path / "lamp" / "test" / "lamp_0900.off")
    layout, found = folder_models(DatasetConfig(source="folder", path=tmp_path))
    assert layout == "modelnet" and list(found) == ["chair", "desk", "lamp"]
    assert [p.name for p in found["lamp"]] == ["lamp_0001.off", "lamp_0900.off"]
    chosen = DatasetConfig(source="folder", path=tmp_path, classes=["lamp", "chair"])
    assert list(folder_models(chosen)[1]) == ["lamp", "chair"]
    with pytest.raises(DatasetLayoutError, match=r"class folder\(s\) not found: sofa"):
        folder_models(DatasetConfig(source="folder", path=tmp_path, classes=["sofa"]))
    with pytest.raises(DatasetLayoutError, match="dataset.path is not set"):
        folder_models(DatasetConfig())
