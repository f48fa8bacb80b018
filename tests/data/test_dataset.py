import json
from pathlib import Path

import pytest
import trimesh

from rapomdp.config import config_from_dict
from rapomdp.data.dataset import (
    duplicate_line,
    load_dataset,
    role_count_lines,
    split_line,
    warning_lines,
)
from rapomdp.data.layouts import DatasetLayoutError
from rapomdp.data.meshes import MeshLoadError, bounding_sphere_radius
from rapomdp.data.splits import TooFewModelsError
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import Workspace
from tests.conftest import SMALL_SPLIT, TEST_CONTEXT


def _folder_dataset(root: Path, per_class: dict[str, int], distinct: bool = False) -> None:
    """Box meshes, ``count`` a class; with ``distinct`` no two files of the folder alike."""
    for c, (name, count) in enumerate(per_class.items()):
        for i in range(count):
            path = root / name / f"m{i}.stl"
            path.parent.mkdir(parents=True, exist_ok=True)
            depth = 0.2 + c * 0.01 if distinct else 0.2
            trimesh.creation.box(extents=(0.1 + i * 0.01, depth, 0.4)).export(path)


def _cfg(root: Path, **dataset: object) -> object:
    dataset = {"split": {**SMALL_SPLIT, **dataset.pop("split", {})}, **dataset}
    return config_from_dict({"dataset": {"source": "folder", "path": str(root), **dataset},
                             "render": {"views": 2}, "camera": {"width": 16, "height": 12}})


def test_folder_dataset_normalised_split_and_cached_on_file_changes(tmp_path: Path) -> None:
    root = tmp_path / "meshes"
    _folder_dataset(root, {"box": 5, "crate": 6})
    ws = Workspace(tmp_path / "ws")
    cfg = _cfg(root)
    run_pipeline(cfg, ws, until="dataset", context=TEST_CONTEXT)
    data = load_dataset(ws.stage_dir("dataset"))
    # the crate's sixth model is an extra training model (dataset.split.extra: train)
    assert data.classes == ["box", "crate"] and len(data.models) == 11
    roles = {(c, r): sum(1 for m in data.models if m.class_name == c and m.role == r)
             for c in data.classes for r in ("train", "volume", "test")}
    assert roles == {("box", "train"): 3, ("box", "volume"): 1, ("box", "test"): 1,
                     ("crate", "train"): 4, ("crate", "volume"): 1, ("crate", "test"): 1}
    assert role_count_lines(ws.stage_dir("dataset")) == [
        "3 train, 1 volume, 1 test model(s) per class (1 classes: box)",
        "4 train, 1 volume, 1 test model(s) per class (1 classes: crate)"]
    for model in data.models:
        assert bounding_sphere_radius(data.mesh(model).vertices) == pytest.approx(0.2)
        assert model.source.endswith(".stl")
    assert run_pipeline(cfg, ws, until="dataset", context=TEST_CONTEXT)[0].cached
    # touching a mesh file changes the stage's key
    (root / "box" / "m0.stl").write_bytes((root / "box" / "m1.stl").read_bytes())
    assert not run_pipeline(cfg, ws, until="dataset", context=TEST_CONTEXT)[0].cached


def test_extra_models_can_be_left_out(tmp_path: Path) -> None:
    root = tmp_path / "meshes"
    _folder_dataset(root, {"box": 5, "crate": 7})
    ws = Workspace(tmp_path / "ws")
    run_pipeline(_cfg(root, split={"extra": "drop"}), ws, until="dataset", context=TEST_CONTEXT)
    data = load_dataset(ws.stage_dir("dataset"))
    assert len(data.models) == 10
    assert role_count_lines(ws.stage_dir("dataset")) == [
        "3 train, 1 volume, 1 test model(s) per class (2 classes: box, crate)"]


def test_folder_dataset_errors_name_the_problem(tmp_path: Path) -> None:
    root = tmp_path / "meshes"
    _folder_dataset(root, {"box": 5, "tiny": 2})
    ws = Workspace(tmp_path / "ws")
    with pytest.raises(TooFewModelsError, match="class 'tiny' has 2 model"):
        run_pipeline(_cfg(root), ws, until="dataset", context=TEST_CONTEXT)
    run_pipeline(_cfg(root, too_few_models="drop"), ws, until="dataset", context=TEST_CONTEXT)
    assert load_dataset(ws.stage_dir("dataset")).classes == ["box"]
    record = json.loads((ws.stage_dir("dataset") / "dataset.json").read_text())
    assert record["dropped"] == {"tiny": 2}
    assert warning_lines(ws.stage_dir("dataset"))[0] == (
        "class 'tiny' has 2 model(s); the split needs 5 (3 train, 1 volume, 1 test): "
        "class(es) left out")
    with pytest.raises(DatasetLayoutError, match="class folder\\(s\\) not found: sofa"):
        run_pipeline(_cfg(root, classes=["box", "sofa"]), ws, until="dataset", context=TEST_CONTEXT)
    (root / "box" / "m3.stl").write_text("solid broken\nthis is not stl\n")
    with pytest.raises(MeshLoadError, match="m3.stl"):
        run_pipeline(_cfg(root, classes=["box"]), Workspace(tmp_path / "ws2"), until="dataset",
                     context=TEST_CONTEXT)
    # the failures left the earlier dataset in place
    assert json.loads((ws.stage_dir("dataset") / "dataset.json").read_text())["classes"] == ["box"]


def test_unknown_procedural_class_is_named(tmp_path: Path) -> None:
    cfg = config_from_dict({"dataset": {"classes": ["cup", "lamp"]}})
    with pytest.raises(DatasetLayoutError, match="unknown procedural class\\(es\\) lamp"):
        run_pipeline(cfg, Workspace(tmp_path / "ws"), until="dataset", context=TEST_CONTEXT)


def test_models_of_two_roles_with_the_same_bytes_are_reported(tmp_path: Path) -> None:
    root = tmp_path / "meshes"
    _folder_dataset(root, {"box": 5, "crate": 5})
    for i in range(1, 5):  # every box the same file: some land in different roles
        (root / "box" / f"m{i}.stl").write_bytes((root / "box" / "m0.stl").read_bytes())
    ws = Workspace(tmp_path / "ws")
    run_pipeline(_cfg(root), ws, until="dataset", context=TEST_CONTEXT)
    line = duplicate_line(ws.stage_dir("dataset"))
    assert line is not None and "have the same bytes as a model of another role" in line
    assert "box" in line and "crate" not in line
    ws2 = Workspace(tmp_path / "ws2")
    _folder_dataset(tmp_path / "distinct", {"box": 5, "crate": 5})
    for i in range(5):  # the fixture's classes share sizes: make every file distinct
        trimesh.creation.box(extents=(0.3, 0.1 + i * 0.01, 0.2)).export(
            tmp_path / "distinct" / "crate" / f"m{i}.stl")
    run_pipeline(_cfg(tmp_path / "distinct"), ws2, until="dataset", context=TEST_CONTEXT)
    assert duplicate_line(ws2.stage_dir("dataset")) is None


def test_a_mesh_file_over_the_cap_is_refused_before_it_is_read(tmp_path: Path) -> None:
    root = tmp_path / "meshes"
    _folder_dataset(root, {"box": 5, "crate": 5})
    big = root / "box" / "m0.ply"
    (root / "box" / "m0.stl").unlink()
    with open(big, "wb") as handle:  # sparse: 2 GB that take no disk and are never read
        handle.truncate(2 * 10**9)
    config = config_from_dict({**_cfg(root).model_dump(mode="json"),
                               "limits": {"mesh_file_mb": 100}})
    with pytest.raises(MeshLoadError, match=r"m0.ply: 2000 MB, over the mesh file cap of 100 MB"):
        run_pipeline(config, Workspace(tmp_path / "ws"), until="dataset", context=TEST_CONTEXT)


def test_auto_split_of_a_folder_of_5_7_and_11_models_a_class(tmp_path: Path) -> None:
    root = tmp_path / "meshes"
    _folder_dataset(root, {"bench": 5, "lamp": 7, "sofa": 11}, distinct=True)
    ws = Workspace(tmp_path / "ws")
    config = config_from_dict({"dataset": {"source": "folder", "path": str(root)}})
    assert config.dataset.split == "auto"  # the default
    run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
    data = load_dataset(ws.stage_dir("dataset"))
    assert len(data.models) == 5 + 7 + 11  # every model used
    assert sorted(m.source for m in data.models) == sorted(
        str(p) for p in root.rglob("*.stl"))
    expected = {"bench": {"train": 3, "volume": 1, "test": 1},
                "lamp": {"train": 3, "volume": 2, "test": 2},
                "sofa": {"train": 4, "volume": 3, "test": 4}}
    assert data.role_counts() == expected
    assert data.held_out_groups == 1
    record = json.loads((ws.stage_dir("dataset") / "dataset.json").read_text())
    assert record["role_counts"] == expected and record["split_rule"] == "auto"
    assert record["held_out_groups"] == 1 and record["dropped"] == {}
    assert split_line(ws.stage_dir("dataset")) == (
        "split: auto (every model used); held-out groups (volume models of the smallest "
        "class): 1 (too few for a leave-one-group-out choice)")
    assert role_count_lines(ws.stage_dir("dataset")) == [
        "3 train, 1 volume, 1 test model(s) per class (1 classes: bench)",
        "3 train, 2 volume, 2 test model(s) per class (1 classes: lamp)",
        "4 train, 3 volume, 4 test model(s) per class (1 classes: sofa)"]
    assert warning_lines(ws.stage_dir("dataset")) == []
    (root / "stool").mkdir()
    for i in range(4):
        trimesh.creation.box(extents=(0.3, 0.1 + i * 0.01, 0.5)).export(
            root / "stool" / f"s{i}.stl")
    with pytest.raises(TooFewModelsError, match="^class 'stool' has 4 model\\(s\\); split: "
                       "auto needs at least 5 a class"):
        run_pipeline(config, ws, until="dataset", context=TEST_CONTEXT)
