"""The ``vptree`` pipeline stage: the VP-tree baseline's classifier and observation model.

Fits a :class:`~rapomdp.recognition.vocabulary_tree.VocabularyTreeClassifier` on the train
models' training-viewsphere renders, classifies every class's volume model(s) at the test
viewpoints X_rho and counts the per-viewpoint confusion P(o | class, x) with pseudo-counts (the
same construction as the CNN's "Classifier" model), and records its single-view accuracy on the
test models at X_rho.

``W/vptree/``: ``vocabulary_tree.npz`` (the classifier), ``observation_model.npz`` with
``vptree`` (V, C, C) and ``classes``, and ``vptree.json`` (classes, train_images,
descriptors_fit, leaves, accuracy_test_xrho, accuracy_volume_xrho, seconds).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from rapomdp.config import Config, VPTreeConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry
from rapomdp.data.test_views import TEST_STREAM, VOLUME_STREAM, xrho_renders
from rapomdp.data.training_views import TrainingViews, load_training_views
from rapomdp.io import save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.progress import track
from rapomdp.recognition.artefacts import (
    VPTREE_CLASSIFIER_FILE,
    VPTREE_MODEL_NAME,
    VPTREE_OBSERVATION_FILE,
    VPTREE_SUMMARY_FILE,
)
from rapomdp.recognition.evaluation import viewpoint_confusion
from rapomdp.recognition.vocabulary_tree import DescriptorParams, VocabularyTreeClassifier
from rapomdp.workspace import StageError, StageInputs

VPTREE_SECTIONS = ("seed", "camera", "render", "viewpoints", "vptree")


def descriptor_params(cfg: VPTreeConfig) -> DescriptorParams:
    return DescriptorParams(cfg.patch_size_m, cfg.patch_samples, cfg.stride_px)


def fit_vptree(config: Config, views: TrainingViews,
               progress: bool = True) -> VocabularyTreeClassifier:
    """The VP-tree classifier fitted on the train models' training-viewsphere renders."""
    dataset = views.dataset
    train = dataset.with_role("train")
    if not train:
        raise StageError(f"{dataset.root}: the dataset has no train models")
    depth, labels = [], []
    for model in track(train, "vptree: loading training views", progress):
        images, _ = views.load(model)
        depth.append(images)
        labels.append(np.full(images.shape[0], dataset.label(model)))
    images = np.concatenate(depth)
    del depth  # one copy of the training images in memory, not two
    cfg = config.vptree
    return VocabularyTreeClassifier.fit(
        images, np.concatenate(labels), dataset.classes, views.intrinsics.fx,
        views.intrinsics.fy, descriptor_params(cfg), config.seed, branching=cfg.branching,
        levels=cfg.levels, max_fit_descriptors=cfg.max_fit_descriptors, top_k=cfg.top_k)


def _xrho_labels(classifier: VocabularyTreeClassifier, dataset: Dataset,
                 models: list[ModelEntry], config: Config, purpose: str) -> list[np.ndarray]:
    """The VP-tree's labels (V,) of each model rendered at X_rho (a task of the stage)."""
    return [classifier.predict(xrho_renders(dataset, model, config, purpose)[1]).argmax(axis=1)
            for model in models]


def xrho_predictions(classifier: VocabularyTreeClassifier, dataset: Dataset,
                     models: list[ModelEntry], config: Config, purpose: str,
                     description: str, progress: bool = True, workers: int = 1,
                     scheduler: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """True labels (M,) and the VP-tree's labels (M, V) of models rendered at X_rho, over
    ``workers`` processes (or the Dask ``scheduler``); the labels do not depend on them.

    In one process each model is a task; otherwise the models go in a few contiguous shares
    per worker, so the classifier travels to the workers a few times, not once per model.
    """
    shares = len(models) if workers <= 1 and scheduler is None else 4 * workers
    groups = [[models[i] for i in share]
              for share in np.array_split(np.arange(len(models)), min(shares, len(models)))]
    predicted = run_tasks(_xrho_labels, [(classifier, dataset, g, config, purpose)
                                         for g in groups],
                          workers, description, progress, scheduler)
    labels = [dataset.label(model) for model in models]
    return np.array(labels, dtype=np.int64), np.stack([p for part in predicted for p in part])


def run_vptree_stage(config: Config, inputs: StageInputs, out: Path,
                     context: RunContext) -> None:
    """Fit the VP-tree, count its per-viewpoint confusion on the volume models at X_rho."""
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    views = load_training_views(inputs.render, inputs.dataset)
    dataset = views.dataset
    classifier = fit_vptree(config, views, context.progress)
    seconds["fit"] = time.perf_counter() - start
    step = time.perf_counter()
    volume_labels, volume_pred = xrho_predictions(
        classifier, dataset, dataset.with_role("volume"), config, VOLUME_STREAM,
        "vptree: volume models at X_rho", context.progress, context.worker_count,
        context.scheduler)
    confusion = viewpoint_confusion(volume_labels, volume_pred, len(dataset.classes),
                                    config.vptree.pseudo_count)
    seconds["observation_model"] = time.perf_counter() - step
    step = time.perf_counter()
    test_models = dataset.with_role("test")
    test_accuracy = None
    if test_models:
        test_labels, test_pred = xrho_predictions(
            classifier, dataset, test_models, config, TEST_STREAM,
            "vptree: test models at X_rho", context.progress, context.worker_count,
            context.scheduler)
        test_accuracy = float((test_pred == test_labels[:, None]).mean())
    seconds["test"] = time.perf_counter() - step
    classifier.save(out / VPTREE_CLASSIFIER_FILE)
    save_npz(out / VPTREE_OBSERVATION_FILE, **{VPTREE_MODEL_NAME: confusion},
             classes=np.array(dataset.classes))
    seconds["total"] = time.perf_counter() - start
    write_json_atomic(out / VPTREE_SUMMARY_FILE, {
        "classes": dataset.classes,
        "train_images": int(classifier.labels.size),
        "descriptors_fit": classifier.fit_descriptors,
        "leaves": classifier.tree.leaves,
        "accuracy_test_xrho": test_accuracy,
        "accuracy_volume_xrho": float((volume_pred == volume_labels[:, None]).mean()),
        "chance": 1.0 / len(dataset.classes),
        "seconds": seconds,
    })


def load_workspace_vptree(stage_dir: str | Path) -> VocabularyTreeClassifier:
    """The vptree stage's classifier (``W/vptree/vocabulary_tree.npz``)."""
    return VocabularyTreeClassifier.load(Path(stage_dir) / VPTREE_CLASSIFIER_FILE)
