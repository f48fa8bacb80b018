import os
from pathlib import Path

import numpy as np
import pytest

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import load_dataset
from rapomdp.data.meshes import bounding_sphere_radius
from rapomdp.data.training_views import load_training_views
from rapomdp.pipeline import run_pipeline, stages_up_to
from rapomdp.workspace import Stage, StageError, StageInputs, Workspace
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

    def good(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
        (out / "result.txt").write_text("good")

    def bad(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
        (out / "result.txt").write_text("half")
        raise RuntimeError("disk on fire")

    ws.run(Stage("s", good, sections=("seed",)), cfg, context=TEST_CONTEXT)
    before = ws.manifest()
    with pytest.raises(RuntimeError, match="disk on fire"):
        ws.run(Stage("s", bad, sections=("seed",)), cfg, force=True, context=TEST_CONTEXT)
    assert (ws.stage_dir("s") / "result.txt").read_text() == "good"
    assert ws.manifest() == before
    assert [p.name for p in workspace_dir.iterdir() if p.name.startswith(".")] == [
        ".rapomdp-workspace"], "the marker only: the scratch folder is gone"


def test_missing_inputs_are_named(workspace_dir: Path) -> None:
    ws = Workspace(workspace_dir)
    stage = Stage("render", lambda c, i, o, x: None, inputs=("dataset",))
    with pytest.raises(StageError, match="needs stage 'dataset', which has not run"):
        ws.run(stage, Config(), context=TEST_CONTEXT)
    with pytest.raises(StageError, match="stage 'dataset' has not been run here; run `rapomdp "
                                         "run --workspace .* --until dataset` first"):
        ws.require("dataset")


def test_stage_inputs_are_typed_folders_and_name_a_missing_upstream(tmp_path: Path) -> None:
    """A stage reads ``inputs.train`` (its folder, or a StageError naming the train stage and
    the reading one); ``inputs.train_dir`` is None when not given (an optional input)."""
    inputs = StageInputs("observe", dataset_dir=str(tmp_path), volume_dir=tmp_path / "v")
    assert inputs.dataset == tmp_path and isinstance(inputs.dataset, Path)  # a str is coerced
    assert inputs.xrho_dir is None
    assert inputs.given() == {"dataset": tmp_path, "volume": tmp_path / "v"}  # pipeline order
    assert repr(inputs) == (f"StageInputs('observe', dataset_dir={str(tmp_path)!r}, "
                            f"volume_dir={str(tmp_path / 'v')!r})")
    with pytest.raises(StageError, match=r"^stage 'observe' needs the folder of stage "
                                         r"'xrho', which it was not given: run `rapomdp "
                                         r"xrho -w WORKSPACE` first"):
        inputs.xrho  # noqa: B018
    with pytest.raises(StageError, match=r"^this stage needs the folder of stage 'train'"):
        StageInputs().train  # noqa: B018
    assert StageInputs.of("train", {"dataset": tmp_path}) == StageInputs(
        "train", dataset_dir=tmp_path)
    with pytest.raises(StageError, match=r"stage 'mine' reads 'fig9', which StageInputs has "
                                         r"no folder for \(it has dataset, render, train"):
        StageInputs.of("mine", {"fig9": tmp_path})


def test_the_workspace_gives_a_stage_the_folders_of_its_graph_inputs(workspace_dir: Path
                                                                     ) -> None:
    ws = Workspace(workspace_dir)
    seen: list[StageInputs] = []
    ws.run(Stage("dataset", lambda c, i, o, x: seen.append(i)), Config(), context=TEST_CONTEXT)
    ws.run(Stage("render", lambda c, i, o, x: seen.append(i), inputs=("dataset",)), Config(),
           context=TEST_CONTEXT)
    assert seen == [StageInputs("dataset"),
                    StageInputs("render", dataset_dir=ws.stage_dir("dataset"))]
    assert ws.inputs(Stage("render", lambda c, i, o, x: None, inputs=("dataset",))) == seen[1]




def test_the_workspace_configuration_is_read_in_one_place(tmp_path: Path) -> None:
    ws = Workspace(tmp_path / "ws")
    with pytest.raises(StageError, match=r"config.yaml: not found; a workspace made by"):
        ws.config()
    fallback = Config(seed=11)
    assert ws.config(default=fallback) is fallback
    chosen = Config(seed=4, viewpoints={"count": 12})
    ws.root.mkdir()
    ws.record_config(chosen)
    assert ws.config() == chosen and ws.config(default=fallback) == chosen
    assert ws.config_path == ws.root / "config.yaml"


def test_staleness_names_the_changed_keys_and_the_stages_after(workspace_dir: Path) -> None:
    cfg = tiny_config()
    ws = Workspace(workspace_dir)
    run_pipeline(cfg, ws, until="render", context=TEST_CONTEXT)
    assert ws.staleness(stages_up_to("render"), cfg) == {}
    changed = tiny_config(seed=4, render={"views": 8})
    stale = ws.staleness(stages_up_to("render"), changed)
    assert stale["dataset"] == ["seed 3 -> 4"]
    assert stale["render"] == ["seed 3 -> 4", "render.views 6 -> 8", "input dataset is stale"]
    only_render = ws.staleness(stages_up_to("render"), tiny_config(render={"views": 8}))
    assert list(only_render) == ["render"]


def test_config_is_recorded_only_with_the_artefacts_it_made(workspace_dir: Path) -> None:
    cfg = tiny_config()
    ws = Workspace(workspace_dir)
    run_pipeline(cfg, ws, until="dataset", context=TEST_CONTEXT)
    assert ws.recorded_config() == cfg

    def fails(config, inputs, out, context):
        (out / "half.npz").write_bytes(b"x")
        raise StageError("it failed")

    other = tiny_config(seed=9)
    with pytest.raises(StageError, match="it failed"):
        ws.run(Stage("broken", fails, sections=("seed",)), other)
    assert ws.recorded_config() == cfg, "a failed stage does not record its configuration"
    assert not [p for p in workspace_dir.iterdir() if ".tmp-" in p.name]


def test_one_run_at_a_time_and_leftovers_of_dead_runs(workspace_dir: Path) -> None:
    import subprocess
    import sys

    from rapomdp.workspace import WorkspaceBusyError

    ws = Workspace(workspace_dir)
    run_pipeline(tiny_config(), ws, until="dataset", context=TEST_CONTEXT)
    os_replace = __import__("os").replace
    scratch = workspace_dir / ".rapomdp-tmp"  # what a run killed mid-swap leaves
    scratch.mkdir()
    os_replace(workspace_dir / "dataset", scratch / "dataset.old-12345")
    (scratch / "render.tmp-12345").mkdir()
    (scratch / ".manifest.json.abc.tmp").write_text("{")
    users = [workspace_dir / ".photos.old-7", workspace_dir / ".render.tmp-1",
             workspace_dir / ".notes.tmp"]  # named like a run's leftovers, but not in scratch
    for path in users[:2]:
        path.mkdir()
    users[2].write_text("mine")
    with ws.locked(), ws.locked():  # the same process may nest
        assert (workspace_dir / "dataset" / "dataset.json").exists(), "moved back"
        assert sorted(p.name for p in workspace_dir.iterdir()) == [
            ".lock", ".notes.tmp", ".photos.old-7", ".rapomdp-workspace", ".render.tmp-1",
            "config.yaml", "dataset", "manifest.json"]
        holder = subprocess.run(
            [sys.executable, "-c", "import sys; from rapomdp.workspace import Workspace\n"
             f"with Workspace({str(workspace_dir)!r}).locked(): pass"],
            capture_output=True, text=True, timeout=120)
        assert holder.returncode == 1
        assert f"in use by another rapomdp run (pid {__import__('os').getpid()})" in holder.stderr
        assert WorkspaceBusyError.__name__ in holder.stderr
        # a hard-linked copy of the workspace shares the lock: named, with what to delete
        copy = workspace_dir.parent / "copy"
        copy.mkdir()
        (copy / ".rapomdp-workspace").write_bytes((workspace_dir / ".rapomdp-workspace")
                                                  .read_bytes())
        os.link(workspace_dir / ".lock", copy / ".lock")
        with pytest.raises(WorkspaceBusyError, match=r"\.lock is a hard link shared with "
                           r"another folder \(a copy made with cp -al\?\), where rapomdp run "
                           rf"pid {os.getpid()} holds it; delete .*copy/\.lock"):
            with Workspace(copy).locked():
                pass
        (copy / ".lock").unlink()
    with Workspace(copy).locked():  # its own lock file: it runs
        assert (copy / ".lock").stat().st_nlink == 1


def test_a_damaged_manifest_is_named(workspace_dir: Path) -> None:
    from rapomdp.io import ArtefactError

    workspace_dir.mkdir()
    ws = Workspace(workspace_dir)
    for content, message in (("[]", "not a rapomdp manifest"), ("{}", "without it"),
                             ('{"stages": {"render": 3}}', "record of stage 'render'")):
        (workspace_dir / "manifest.json").write_text(content)
        with pytest.raises(ArtefactError, match=message):
            ws.manifest()


def test_only_a_workspace_or_an_empty_folder_is_written_to(tmp_path: Path) -> None:
    """A new or empty folder becomes a workspace (its marker); a workspace made before markers
    (a valid manifest) gets one at its next locked run; any other folder is refused naming it,
    its files (a .lock of its own too) untouched."""
    import json

    from rapomdp.workspace import MARKER, NotAWorkspaceError

    new = Workspace(tmp_path / "a" / "new")
    with new.locked():
        pass
    assert json.loads((new.root / MARKER).read_text())["format"] == 1
    (tmp_path / "empty").mkdir()
    assert Workspace(tmp_path / "empty").claim() is False
    assert (tmp_path / "empty" / MARKER).is_file()

    older = Workspace(tmp_path / "older")
    older.root.mkdir()
    (older.root / "manifest.json").write_text('{"stages": {}}')
    assert older.check() == "older"
    with older.locked():
        assert (older.root / MARKER).is_file()
    assert older.check() == "workspace"

    user = tmp_path / "user"
    (user / "train").mkdir(parents=True)
    (user / ".lock").write_text("mine")
    for ws in (Workspace(user), Workspace(user / "train" / ".." )):
        with pytest.raises(NotAWorkspaceError, match=f"{user}.*: not a rapomdp workspace"):
            with ws.locked():
                pass
    assert (user / ".lock").read_text() == "mine" and sorted(os.listdir(user)) == [
        ".lock", "train"]
    (user / "file").write_text("x")
    with pytest.raises(NotAWorkspaceError, match="file: not a folder"):
        Workspace(user / "file").claim()


def test_a_stage_folder_is_replaced_only_when_the_project_made_it(workspace_dir: Path) -> None:
    ws = Workspace(workspace_dir)
    cfg = Config()

    def good(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
        (out / "result.txt").write_text("good")

    stage = Stage("s", good, sections=("seed",))
    ws.claim()  # a new workspace, in which the user then makes a folder
    (workspace_dir / "s").mkdir()
    (workspace_dir / "s" / "mine.txt").write_text("the user's")
    with pytest.raises(StageError, match="s: a folder rapomdp did not make"):
        ws.run(stage, cfg, context=TEST_CONTEXT)
    (workspace_dir / "s" / "mine.txt").rename(workspace_dir / "mine.txt")
    (workspace_dir / "s").rmdir()
    ws.run(stage, cfg, context=TEST_CONTEXT)
    os.replace(workspace_dir / "s", workspace_dir / "elsewhere")
    (workspace_dir / "s").symlink_to(workspace_dir / "elsewhere")
    assert ws.run(stage, cfg, context=TEST_CONTEXT).cached, "read through the link"
    with pytest.raises(StageError, match="s: a symbolic link .*must be a folder"):
        ws.run(stage, cfg, force=True, context=TEST_CONTEXT)
    assert (workspace_dir / "s").is_symlink() and (workspace_dir / "mine.txt").exists()
    assert sorted(os.listdir(workspace_dir)) == [
        ".rapomdp-workspace", "config.yaml", "elsewhere", "manifest.json", "mine.txt", "s"]


def test_a_lost_config_is_rebuilt_from_the_stage_records(workspace_dir: Path) -> None:
    """Without W/config.yaml the configuration comes from the manifest's stage records (the
    stage that finished last wins), never the default that would redo the stages."""
    from rapomdp.pipeline import resolve_config

    ws = Workspace(workspace_dir)
    cfg = tiny_config()
    run_pipeline(cfg, ws, until="dataset", context=TEST_CONTEXT)
    ws.config_path.unlink()
    notes: list[str] = []
    config, stale = resolve_config(ws, on_note=notes.append)
    assert stale == {} and config.dataset.classes == ["cup", "mug", "bicycle"]
    assert config.seed == 3 and config.render == Config().render, "no stage read render"
    assert len(notes) == 1 and "rebuilt from the stage records" in notes[0]
    assert ws.recorded_config() == config and ws.config() == config
    assert all(r.cached for r in run_pipeline(config, ws, until="dataset",
                                              context=TEST_CONTEXT))
    assert ws.config_path.exists(), "written back by a run that agrees with the records"
