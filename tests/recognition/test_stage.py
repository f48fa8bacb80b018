"""The train and classifier_eval stages end to end on a tiny workspace, and the CLI's errors."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from rapomdp.cli import app
from rapomdp.config import config_from_dict
from rapomdp.context import RunContext
from rapomdp.data.dataset import load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import load_xrho_views
from rapomdp.data.training_views import load_training_views
from rapomdp.io import load_npz, read_json
from rapomdp.pipeline import get_stage, run_pipeline
from rapomdp.recognition.artefacts import load_xrho_probabilities
from rapomdp.recognition.classifier import META_FILE, CheckpointMismatchError
from rapomdp.recognition.network import DepthEnsemble
from rapomdp.recognition.stage import load_stage_classifier, run_train_stage, train_config_hash
from rapomdp.recognition.training import collect_views, validation_mask
from rapomdp.workspace import StageInputs, Workspace
from tests.conftest import SMALL_SPLIT, TEST_CONTEXT

TINY = {
    "dataset": {"classes": ["cup", "bottle", "chair"], "split": SMALL_SPLIT},
    "camera": {"width": 80, "height": 60},
    "render": {"views": 12},
    "viewpoints": {"count": 8},
    "train": {"epochs": 2, "width": 0.125, "batch_size": 16,
              "preprocess": {"input_size_px": 32}},
}


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    root = tmp_path_factory.mktemp("ws")
    config = config_from_dict(TINY)
    run_pipeline(config, Workspace(root), until="classifier_eval", context=TEST_CONTEXT)
    (root / "tiny.yaml").write_text(yaml.safe_dump(TINY))
    return root, config


def test_train_stage_writes_a_checked_checkpoint(workspace):
    root, config = workspace
    meta = read_json(root / "train" / META_FILE)
    assert meta["classes"] == ["cup", "bottle", "chair"]
    assert meta["config_hash"] == train_config_hash(config)
    assert meta["preprocessing"]["input_size_px"] == 32
    history = list(csv.DictReader((root / "train" / "history.csv").open()))
    assert [int(r["epoch"]) for r in history] == [1, 2]
    metrics = read_json(root / "train" / "metrics.json")
    # 3 classes x 3 train models x 12 views, 10 % of each model's views held out (1 of 12)
    assert metrics["train_images"] == 3 * 3 * 11 and metrics["validation_images"] == 3 * 3 * 1
    classifier = load_stage_classifier(config, root / "train", ["cup", "bottle", "chair"])
    assert classifier.classes == ["cup", "bottle", "chair"]
    with pytest.raises(CheckpointMismatchError, match="class list"):
        load_stage_classifier(config, root / "train", ["cup", "bottle", "table"])
    changed = config_from_dict({**TINY, "train": {**TINY["train"], "epochs": 3}})
    with pytest.raises(CheckpointMismatchError, match="configuration hash"):
        load_stage_classifier(changed, root / "train", ["cup", "bottle", "chair"])


def test_an_ensemble_train_stage_writes_its_members_and_the_ensembles_accuracy(workspace,
                                                                              tmp_path):
    root, config = workspace
    classes = ["cup", "bottle", "chair"]
    ensemble = config_from_dict({**TINY, "train": {**TINY["train"], "ensemble": 2}})
    inputs = StageInputs.of("train", {"dataset": root / "dataset", "render": root / "render"})
    run_train_stage(ensemble, inputs, tmp_path, TEST_CONTEXT)
    history = list(csv.DictReader((tmp_path / "history.csv").open()))
    assert [(int(r["member"]), int(r["epoch"])) for r in history] == [(0, 1), (0, 2), (1, 1),
                                                                       (1, 2)]
    metrics = read_json(tmp_path / "metrics.json")
    assert metrics["ensemble"] == 2
    assert metrics["member_validation_accuracy"] == [float(history[1]["val_accuracy"]),
                                                     float(history[3]["val_accuracy"])]
    classifier = load_stage_classifier(ensemble, tmp_path, classes)
    assert isinstance(classifier.network, DepthEnsemble)
    # the validation accuracy is the ensemble's own, on the train stage's held-out views
    data = collect_views(load_training_views(root / "render", root / "dataset"), "train")
    held = validation_mask(data, 0.1, class_seed(ensemble.train_seed, "train/validation"))
    assert held.sum() == metrics["validation_images"] == 9
    predicted = classifier.predict(data.depth[held]).argmax(axis=1)
    assert metrics["final_validation_accuracy"] == pytest.approx(
        float((predicted == data.labels[held]).mean()))
    # the single classifier's workspace does not take it, nor it the single classifier
    with pytest.raises(CheckpointMismatchError, match="configuration hash"):
        load_stage_classifier(config, tmp_path, classes)
    with pytest.raises(CheckpointMismatchError, match="configuration hash"):
        load_stage_classifier(ensemble, root / "train", classes)


def test_ensemble_members_trained_in_worker_processes_are_those_of_one_process(workspace,
                                                                              tmp_path):
    root, _ = workspace
    ensemble = config_from_dict({**TINY, "train": {**TINY["train"], "ensemble": 3}})
    inputs = StageInputs.of("train", {"dataset": root / "dataset", "render": root / "render"})
    run_train_stage(ensemble, inputs, tmp_path / "one", TEST_CONTEXT)
    run_train_stage(ensemble, inputs, tmp_path / "two",
                    RunContext(workers=2, threads=1, progress=False))
    assert (tmp_path / "one" / "classifier.pt").read_bytes() == \
        (tmp_path / "two" / "classifier.pt").read_bytes()
    rows = [list(csv.DictReader((tmp_path / run / "history.csv").open()))
            for run in ("one", "two")]
    assert [(r["member"], r["val_accuracy"]) for r in rows[0]] == \
        [(r["member"], r["val_accuracy"]) for r in rows[1]]
    metrics = [read_json(tmp_path / run / "metrics.json") for run in ("one", "two")]
    assert metrics[0]["final_validation_accuracy"] == metrics[1]["final_validation_accuracy"]


def test_the_stored_batch_outputs_give_the_labels_of_one_image_at_a_time(workspace):
    root, config = workspace
    dataset = load_dataset(root / "dataset")
    classifier = load_stage_classifier(config, root / "train", dataset.classes)
    stored = load_xrho_probabilities(root / "classifier_eval")
    images = load_xrho_views(root / "xrho", dataset)
    models = dataset.with_role("test") + dataset.with_role("volume")
    batched = np.stack([stored.of(m) for m in models])  # every volume and test model
    alone = np.stack([np.concatenate([classifier.predict(d) for d in images.load(m).sensed])
                      for m in models])
    # the closed loop and observe read these: the same labels, the last bits aside
    np.testing.assert_array_equal(batched.argmax(axis=2), alone.argmax(axis=2))
    np.testing.assert_allclose(batched, alone, atol=1e-5)


def test_classifier_eval_reports_consistent_figures(workspace):
    root, _ = workspace
    out = root / "classifier_eval"
    metrics = read_json(out / "metrics.json")
    arrays = load_npz(out / "probabilities.npz")
    assert arrays["xrho"].shape == (3, 8, 3) and arrays["sphere"].shape == (3, 12, 3)
    np.testing.assert_allclose(arrays["xrho"].sum(axis=2), 1.0, atol=1e-5)
    labels = arrays["labels"]
    accuracy = (arrays["xrho"].argmax(axis=2) == labels[:, None]).mean()
    assert metrics["xrho"]["accuracy"] == pytest.approx(accuracy)
    assert metrics["xrho"]["chance"] == pytest.approx(1 / 3)
    assert np.mean(metrics["per_view_accuracy_xrho"]) == pytest.approx(accuracy)
    rows = list(csv.reader((out / "confusion_xrho.csv").open()))
    assert rows[0][1:] == ["cup", "bottle", "chair"]
    counts = np.array([[int(v) for v in row[1:]] for row in rows[1:]])
    assert counts.sum() == 3 * 8 and (counts.sum(axis=1) == 8).all()
    assert np.trace(counts) / counts.sum() == pytest.approx(accuracy)
    for name in ("confusion_xrho.png", "confusion_sphere.png", "accuracy_hemisphere.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_refuses_a_checkpoint_for_other_classes(workspace):
    root, _ = workspace
    meta_path = root / "train" / META_FILE
    original = meta_path.read_text()
    meta = json.loads(original)
    meta["classes"] = ["cup", "bottle", "table"]
    meta_path.write_text(json.dumps(meta))
    try:
        result = CliRunner().invoke(app, ["evaluate-classifier", "-w", str(root), "-c",
                                          str(root / "tiny.yaml"), "--force", "--threads", "1"])
    finally:
        meta_path.write_text(original)
    assert result.exit_code == 2
    assert "class list does not match" in result.output
    assert "classifier.json" in result.output
    assert (root / "classifier_eval" / "metrics.json").exists()  # the earlier result survives


def _same_arrays(a, b) -> bool:
    x, y = load_npz(a), load_npz(b)
    return x.keys() == y.keys() and all(np.array_equal(x[k], y[k]) for k in x)


def test_render_and_classifier_eval_over_two_workers_write_what_one_process_does(
        workspace, tmp_path):
    from rapomdp.context import RunContext
    from rapomdp.pipeline import get_stage
    from rapomdp.workspace import StageInputs

    root, config = workspace
    two = RunContext(workers=2, threads=1, progress=False)
    for name in ("render", "classifier_eval"):
        stage = get_stage(name)
        out = tmp_path / name
        out.mkdir()
        stage.run(config, StageInputs.of(name, {i: root / i for i in stage.inputs}), out, two)
        mine = sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())
        theirs = sorted(p.relative_to(root / name) for p in (root / name).rglob("*")
                        if p.is_file() and p.name != "stage.json")
        assert mine == theirs
        for rel in mine:
            if rel.suffix == ".npz":
                assert _same_arrays(out / rel, root / name / rel), rel
        if name == "classifier_eval":
            assert read_json(out / "metrics.json") == read_json(root / name / "metrics.json")


def test_train_stage_fine_tunes_a_backbone_and_records_it(workspace, tmp_path):
    from rapomdp.config import TrainConfig
    from rapomdp.recognition.backbone import load_backbone
    from tests.recognition.test_backbone import tiny_backbone

    root, config = workspace
    train = TrainConfig(**TINY["train"])
    path = tiny_backbone(tmp_path / "b.pt", train)
    tuned = config_from_dict({**TINY, "train": {**TINY["train"], "backbone": str(path)}})
    out = tmp_path / "train"
    out.mkdir()
    run_train_stage(tuned, Workspace(root).inputs(get_stage("train")), out, TEST_CONTEXT)
    metrics = read_json(out / "metrics.json")
    assert metrics["backbone"] == {"backbone": str(path), "file": "b.pt",
                                   "sha256": load_backbone(path).sha256}
    scratch = read_json(root / "train" / "metrics.json")
    assert "backbone" not in scratch
    # the checkpoint carries its configuration's hash: the scratch one does not fit it
    assert train_config_hash(tuned) != train_config_hash(config)
    assert read_json(out / META_FILE)["config_hash"] == train_config_hash(tuned)
