from pathlib import Path

import numpy as np
import pytest

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import load_dataset
from rapomdp.data.meshes import bounding_sphere_radius
from rapomdp.data.training_views import load_training_views
from rapomdp.pipeline import run_pipeline
from rapomdp.workspace import Stage, StageError, Workspace
from tests.conftest import TEST_CONTEXT, tiny_config


def test_pipeline_builds_caches_and_reruns_only_what_changed(workspace_dir: Path) -> None:
    cfg = tiny_config()
    ws = Workspace(workspace_dir)
    first = run_pipeline(cfg, ws, until="render", context=TEST_CONTEXT)
    assert [(r.name, r.cached) for r in first] == [("dataset", False), ("render", False)]
    manifest = ws.manifest()
    assert "meshes/cup/cup_000.npz" in manifest["stages"]["dataset"]["files"] or any(
        f.startswith("meshes/cup/") for f in manifest["stages"]["dataset"]["files"])
    assert manifest["stages"]["render"]["config"]["render"]["views"] == 6

    again = run_pipeline(cfg, ws, until="render", context=TEST_CONTEXT)
    assert all(r.cached for r in again)

    more_views = tiny_config(render={"views": 8})
    third = run_pipeline(more_views, ws, until="render", context=TEST_CONTEXT)
    assert [(r.name, r.cached) for r in third] == [("dataset", True), ("render", False)]

    forced = run_pipeline(more_views, ws, until="render", force=["dataset"], context=TEST_CONTEXT)
    assert [r.cached for r in forced] == [False, True]


def test_dataset_and_render_artefacts(workspace_dir: Path) -> None:
    cfg = tiny_config()
    ws = Workspace(workspace_dir)
    run_pipeline(cfg, ws, until="render", context=TEST_CONTEXT)
    dataset = load_dataset(ws.stage_dir("dataset"))
    assert dataset.classes == ["cup", "mug", "bicycle"]
    assert len(dataset.models) == 15
    for role, count in (("train", 9), ("volume", 3), ("test", 3)):
        assert len(dataset.with_role(role)) == count
    mesh = dataset.mesh(dataset.models[0])
    assert bounding_sphere_radius(mesh.vertices) == pytest.approx(0.2)
    assert mesh.vertices[:, 2].min() == pytest.approx(0.0)
    views = load_training_views(ws.stage_dir("render"), ws.stage_dir("dataset"))
    depth, poses = views.load(dataset.models[0])
    assert depth.shape == (6, 30, 40) and poses.shape == (6, 4, 4)
    assert np.all((depth > 0).sum(axis=(1, 2)) > 0)
    # the views surround the centroid at the configured radius
    centres = poses[:, :3, 3] - dataset.models[0].centroid
    np.testing.assert_allclose(np.linalg.norm(centres, axis=1), 0.6)
    # same seed, same artefacts
    other = Workspace(workspace_dir.parent / "other")
    run_pipeline(cfg, other, until="render", context=TEST_CONTEXT)
    np.testing.assert_array_equal(
        load_training_views(other.stage_dir("render"), other.stage_dir("dataset"))
        .load(dataset.models[0])[0], depth)


def test_a_failed_stage_leaves_earlier_results_intact(workspace_dir: Path) -> None:
    ws = Workspace(workspace_dir)
    cfg = Config()

    def good(config: Config, inputs: dict, out: Path, context: RunContext) -> None:
        (out / "result.txt").write_text("good")

    def bad(config: Config, inputs: dict, out: Path, context: RunContext) -> None:
        (out / "result.txt").write_text("half")
        raise RuntimeError("disk on fire")

    ws.run(Stage("s", good, sections=("seed",)), cfg, context=TEST_CONTEXT)
    before = ws.manifest()
    with pytest.raises(RuntimeError, match="disk on fire"):
        ws.run(Stage("s", bad, sections=("seed",)), cfg, force=True, context=TEST_CONTEXT)
    assert (ws.stage_dir("s") / "result.txt").read_text() == "good"
    assert ws.manifest() == before
    assert [p.name for p in workspace_dir.iterdir() if p.name.startswith(".")] == []


def test_missing_inputs_are_named(workspace_dir: Path) -> None:
    ws = Workspace(workspace_dir)
    stage = Stage("render", lambda c, i, o, x: None, inputs=("dataset",))
    with pytest.raises(StageError, match="needs stage 'dataset', which has not run"):
        ws.run(stage, Config(), context=TEST_CONTEXT)
    with pytest.raises(StageError, match="stage 'dataset' has not been run here; run `rapomdp "
                                         "run --workspace .* --until dataset` first"):
        ws.require("dataset")




def test_the_workspace_configuration_is_read_in_one_place(tmp_path: Path) -> None:
    ws = Workspace(tmp_path / "ws")
    with pytest.raises(StageError, match=r"config.yaml: not found; a workspace made by"):
        ws.config()
    fallback = Config(seed=11)
    assert ws.config(default=fallback) is fallback
    chosen = Config(seed=4, viewpoints={"count": 12})
    ws.save_config(chosen)
    assert ws.config() == chosen and ws.config(default=fallback) == chosen
    assert ws.config_path == ws.root / "config.yaml"
