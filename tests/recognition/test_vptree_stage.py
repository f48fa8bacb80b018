"""The vptree stage: the VP-tree baseline fitted, its observation model and its held-out
temperature, the summary, the CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from rapomdp.cli import app
from rapomdp.config import VPTreeConfig
from rapomdp.data.dataset import load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import TEST_STREAM, load_xrho_views, xrho_renders
from rapomdp.data.training_views import load_training_views
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import load_npz, read_json
from rapomdp.pipeline import run_pipeline
from rapomdp.recognition.belief import (
    TEMPERATURE_NEIGHBOURS,
    TEMPERATURE_WALK_LENGTH,
    TEMPERATURE_WALKS_PER_ROW,
    fit_temperature,
    random_walks,
    temper,
)
from rapomdp.recognition.evaluation import viewpoint_confusion
from rapomdp.recognition.vptree_stage import (
    fit_vptree,
    load_workspace_vptree,
    vptree_observation,
    xrho_predictions,
)
from rapomdp.workspace import Workspace
from tests.conftest import TEST_CONTEXT, tiny_config


def test_vptree_stage_writes_a_normalised_observation_model(tmp_path: Path) -> None:
    config = tiny_config(vptree={"branching": 4, "levels": 2})
    workspace = Workspace(tmp_path / "ws")
    results = run_pipeline(config, workspace, until="vptree", context=TEST_CONTEXT)
    assert [r.name for r in results] == ["dataset", "render", "xrho", "vptree"]
    stage = workspace.root / "vptree"
    model = load_npz(stage / "observation_model.npz")
    classes = ["cup", "mug", "bicycle"]
    assert [str(c) for c in model["classes"]] == classes
    p = model["vptree"]
    assert p.shape == (16, 3, 3) and np.all(p > 0)
    np.testing.assert_allclose(p.sum(axis=2), 1.0, atol=1e-9)
    summary = read_json(stage / "vptree.json")
    assert summary["classes"] == classes and summary["leaves"] == 16
    assert summary["train_images"] == 3 * 3 * 6  # 3 classes x 3 train models x 6 views
    assert 0.0 <= summary["accuracy_test_xrho"] <= 1.0
    assert set(summary["seconds"]) >= {"fit", "observation_model", "test", "total"}
    classifier = load_workspace_vptree(stage)
    assert classifier.classes == classes and classifier.tree.leaves == 16
    # fitted again from its section and the seed alone, without a pipeline configuration
    views = load_training_views(workspace.root / "render", workspace.root / "dataset")
    again = fit_vptree(views, VPTreeConfig(branching=4, levels=2), seed=3, progress=False)
    assert again.classes == classes and again.tree.leaves == 16 and again.labels.size == 54
    assert again.fit_descriptors == summary["descriptors_fit"]
    sample = views.load(views.dataset.with_role("train")[0])[0]
    np.testing.assert_array_equal(again.predict(sample), classifier.predict(sample))
    # the models at X_rho over two worker processes: the labels of one process
    dataset = load_dataset(workspace.root / "dataset")
    models = dataset.with_role("test") + dataset.with_role("volume")
    images = load_xrho_views(workspace.root / "xrho", dataset)
    alone = xrho_predictions(classifier, images, models, "", False)
    shared = xrho_predictions(classifier, images, models, "", False, 2)
    assert alone[1].shape == (len(models), 16)
    assert all(np.array_equal(a, b) for a, b in zip(alone, shared, strict=True))
    # the stored images are the ones each model's own noise stream renders
    rendered = classifier.predict(xrho_renders(dataset, models[0], TEST_STREAM, config.seed,
                                               config.viewpoints, config.camera,
                                               config.render.noise)[1])
    assert np.array_equal(alone[1][0], rendered.argmax(axis=1))
    # one volume model per class at 16 viewpoints and pseudo-count a: n(c, x) = 1, so each
    # row is (1 + a) / (1 + 3a) on the label seen and a / (1 + 3a) elsewhere
    a = config.vptree.pseudo_count
    np.testing.assert_allclose(p.max(axis=2), (1 + a) / (1 + 3 * a))
    # one volume model per class is one group: nothing to hold out, the raw confusion
    assert float(model["temperature"]) == 1.0 and np.array_equal(model["untempered"], p)
    assert summary["temperature"] == 1.0 and summary["held_out_belief"] == {}
    assert summary["belief_correction"] == "temperature"
    assert "0 held-out group(s)" in summary["temperature_note"]
    # the command line: cached now, and it prints the accuracy
    config_path = tmp_path / "tiny.yaml"
    config_path.write_text(config.to_yaml())
    result = CliRunner().invoke(app, ["vptree", "-w", str(workspace.root), "-c",
                                      str(config_path)])
    assert result.exit_code == 0, result.output
    assert "vptree" in result.output and "cached" in result.output
    shown = f"test models at X_rho: {summary['accuracy_test_xrho']:.1%}"
    assert shown in " ".join(result.output.split())
    assert "temperature (held out): 1.000" in " ".join(result.output.split())


def _by_hand(labels: np.ndarray, predicted: np.ndarray, groups: np.ndarray, classes: int,
             pseudo_count: float, directions: np.ndarray, rng: np.random.Generator) -> float:
    """The temperature fitted by hand: every group held out, scored by the confusion of the
    others, on the walks the stage draws (starts, then moves, from ``rng``)."""
    folds = np.unique(groups)
    models = [viewpoint_confusion(labels[groups != g], predicted[groups != g], classes,
                                  pseudo_count) for g in folds]
    row_model = np.searchsorted(folds, groups)
    walk_row = np.repeat(np.arange(len(labels)), TEMPERATURE_WALKS_PER_ROW)
    starts = rng.integers(0, len(directions), size=walk_row.size)
    walks = random_walks(directions, starts, TEMPERATURE_WALK_LENGTH, TEMPERATURE_NEIGHBOURS,
                         rng)
    return fit_temperature(models, row_model, labels, predicted, walks, walk_row)


def test_vptree_temperature_is_fitted_on_held_out_walks_over_the_volume_groups() -> None:
    """Planted: 3 classes, 3 volume models each (groups 0-2), 16 views; a model's label is
    one draw repeated at every view (right with probability 0.7): the views are perfectly
    correlated, naive Bayes counts one piece of evidence six times, and t drops well below 1."""
    rng = np.random.default_rng(11)
    classes, views = 3, 16
    labels = np.repeat(np.arange(classes), 3)
    groups = np.tile(np.arange(3), classes)
    right = rng.random(labels.size) < 0.7
    drawn = np.where(right, labels, (labels + rng.integers(1, classes, labels.size)) % classes)
    predicted = np.repeat(drawn[:, None], views, axis=1)
    directions = fibonacci_directions(views, hemisphere=True)
    cfg = VPTreeConfig()
    fitted = vptree_observation(labels, predicted, groups, classes, cfg, directions,
                                np.random.default_rng(5))
    t = _by_hand(labels, predicted, groups, classes, cfg.pseudo_count, directions,
                 np.random.default_rng(5))
    assert fitted.temperature == t and t < 0.6 and fitted.note is None
    raw = viewpoint_confusion(labels, predicted, classes, cfg.pseudo_count)
    np.testing.assert_array_equal(fitted.untempered, raw)
    np.testing.assert_allclose(fitted.model, temper(raw, t))
    report = fitted.held_out_belief
    assert report["temperature"] == t
    assert report["log_loss_tempered"] < report["log_loss_naive"]
    # naive Bayes is overconfident after six views; the tempered belief is nearer its accuracy
    gap = {k: report[f"belief_last_{k}"] - report["accuracy_last"] for k in ("naive", "tempered")}
    assert gap["naive"] > 0.1 and abs(gap["tempered"]) < gap["naive"]
    # one group (one volume model per class): t = 1, and why
    one = vptree_observation(labels, predicted, np.zeros_like(groups), classes, cfg,
                             directions, np.random.default_rng(5))
    assert one.temperature == 1.0 and one.held_out_belief == {}
    np.testing.assert_array_equal(one.model, raw)
    assert one.note is not None and "0 held-out group(s)" in one.note


def test_vptree_stage_tempers_its_model_over_two_volume_models_per_class(tmp_path: Path
                                                                         ) -> None:
    config = tiny_config(vptree={"branching": 4, "levels": 2},
                         dataset={"classes": ["cup", "mug", "bicycle"],
                                  "split": {"train": 2, "volume": 2, "test": 1}})
    workspace = Workspace(tmp_path / "ws")
    run_pipeline(config, workspace, until="vptree", context=TEST_CONTEXT)
    stage = workspace.root / "vptree"
    model, summary = load_npz(stage / "observation_model.npz"), read_json(stage / "vptree.json")
    # the stage's labels of the volume models, by hand: the k-th of each class is group k
    dataset = load_dataset(workspace.root / "dataset")
    volume = dataset.with_role("volume")
    labels, predicted = xrho_predictions(load_workspace_vptree(stage),
                                         load_xrho_views(workspace.root / "xrho", dataset),
                                         volume, "", False)
    groups = np.array([[m for m in volume if m.class_name == v.class_name].index(v)
                       for v in volume])
    assert sorted(groups.tolist()) == [0, 0, 0, 1, 1, 1]
    t = _by_hand(labels, predicted, groups, 3, config.vptree.pseudo_count,
                 fibonacci_directions(16, hemisphere=True),
                 class_seed(config.seed, "vptree/temperature"))
    assert summary["temperature"] == t == float(model["temperature"])
    assert summary["temperature_note"] is None
    np.testing.assert_array_equal(model["untempered"], viewpoint_confusion(
        labels, predicted, 3, config.vptree.pseudo_count))
    np.testing.assert_allclose(model["vptree"], temper(model["untempered"], t))
    # the held-out evidence the fit read, saved for the held-out closed loop
    np.testing.assert_array_equal(model["volume_labels"], labels)
    np.testing.assert_array_equal(model["volume_predictions"], predicted)
    np.testing.assert_array_equal(model["volume_groups"], groups)
    held = summary["held_out_belief"]
    assert held["temperature"] == t and set(held) >= {
        "log_loss_naive", "log_loss_tempered", "ece_first_naive", "ece_first_tempered",
        "ece_last_naive", "ece_last_tempered", "accuracy_last"}
