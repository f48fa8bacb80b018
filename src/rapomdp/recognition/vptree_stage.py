"""The ``vptree`` pipeline stage: the VP-tree baseline's classifier and observation model.

Fits a :class:`~rapomdp.recognition.vocabulary_tree.VocabularyTreeClassifier` on the train
models' training-viewsphere renders, classifies every class's volume model(s) at the test
viewpoints X_rho and counts the per-viewpoint confusion P(o | class, x) with pseudo-counts (the
same construction as the CNN's "Classifier" model), tempers it for a multi-view belief with the
likelihood temperature fitted on held-out walks (the k-th volume model of each class is
held-out group k, as the observe stage's evidence), and records its
single-view accuracy on the test models at X_rho.

``W/vptree/``: ``vocabulary_tree.npz`` (the classifier), ``observation_model.npz`` with
``vptree`` (V, C, C) the tempered model (the planner's and the belief's), ``untempered`` the
raw confusion, ``temperature``, ``declared_temperature`` (what the belief reports after its
views is b ** a: a fitted where longer held-out walks stop; absent without two held-out
groups) with ``declared_thresholds`` and ``declared_threshold_temperatures`` (a fitted at each
stop threshold alone), ``classes`` and the held-out evidence it was fitted on
(``volume_labels`` (M,), ``volume_predictions`` (M, V), ``volume_groups`` (M,)), and
``vptree.json`` (classes, train_images, descriptors_fit, leaves, accuracy_test_xrho,
accuracy_volume_xrho, belief_correction, temperature, temperature_note, held_out_belief,
declared_confidence, seconds).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rapomdp.config import Config, VPTreeConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import ModelEntry, class_ranks
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import XrhoViews, load_xrho_views
from rapomdp.data.training_views import TrainingViews, load_training_views
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.processes import WorkerPool
from rapomdp.progress import track
from rapomdp.recognition.artefacts import (
    VPTREE_CLASSIFIER_FILE,
    VPTREE_MODEL_NAME,
    VPTREE_OBSERVATION_FILE,
    VPTREE_OUTPUTS_FILE,
    VPTREE_SUMMARY_FILE,
)
from rapomdp.recognition.belief import (
    DECLARED_WALK_LENGTH,
    DeclaredConfidence,
    declared_confidence,
    fit_temperature,
    fold_of_rows,
    held_out_groups,
    held_out_walks,
    temper,
    walk_calibration,
    walk_log_beliefs,
)
from rapomdp.recognition.evaluation import viewpoint_confusion
from rapomdp.recognition.vocabulary_tree import DescriptorParams, VocabularyTreeClassifier
from rapomdp.workspace import StageError, StageInputs


def descriptor_params(cfg: VPTreeConfig) -> DescriptorParams:
    return DescriptorParams(cfg.patch_size_m, cfg.patch_samples, cfg.stride_px)


def fit_vptree(views: TrainingViews, cfg: VPTreeConfig | None = None, seed: int = 0,
               progress: bool = True) -> VocabularyTreeClassifier:
    """The VP-tree classifier fitted on the train models' training-viewsphere renders.

    Args:
        views: The render stage's training views (the train models' depth images (N, H, W)
            in metres and the camera's intrinsics).
        cfg: The ``vptree`` section: the descriptors' patch and stride, the tree's branching
            and levels (None: the defaults).
        seed: The configuration's ``seed`` (the descriptors sampled for the fit, k-means).
        progress: Show a progress bar while the views load.

    Returns:
        The fitted :class:`~rapomdp.recognition.vocabulary_tree.VocabularyTreeClassifier`
        over the dataset's classes (``predict`` gives (N, C) class probabilities).

    Raises:
        StageError: The dataset has no train models.
    """
    dataset = views.dataset
    train = dataset.with_role("train")
    if not train:
        raise StageError(f"{dataset.root}: the dataset has no train models")
    depth, labels = [], []
    for model in track(train, "vptree: loading training views", progress, unit="models"):
        images, _ = views.load(model)
        depth.append(images)
        labels.append(np.full(images.shape[0], dataset.label(model)))
    images = np.concatenate(depth)
    del depth  # one copy of the training images in memory, not two
    cfg = VPTreeConfig() if cfg is None else cfg
    return VocabularyTreeClassifier.fit(
        images, np.concatenate(labels), dataset.classes, views.intrinsics.fx,
        views.intrinsics.fy, descriptor_params(cfg), seed, branching=cfg.branching,
        levels=cfg.levels, max_fit_descriptors=cfg.max_fit_descriptors, top_k=cfg.top_k)


def _xrho_outputs(classifier: VocabularyTreeClassifier, images: XrhoViews,
                  models: list[ModelEntry]) -> list[np.ndarray]:
    """The VP-tree's outputs (V, C) on each model's images at X_rho (a task of the stage)."""
    return [classifier.predict(images.load(model).sensed) for model in models]


def xrho_outputs(classifier: VocabularyTreeClassifier, images: XrhoViews,
                 models: list[ModelEntry], description: str, progress: bool = True,
                 workers: int = 1, scheduler: str | None = None,
                 pool: WorkerPool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """True labels (M,) and the VP-tree's outputs (M, V, C) on models at X_rho (the xrho
    stage's ``images``), over ``workers`` processes (``pool``'s when it has as many; or the
    Dask ``scheduler``); the outputs do not depend on them, nor on how many images one call
    classifies.

    In one process each model is a task; otherwise the models go in a few contiguous shares
    per worker, so the classifier travels to the workers a few times, not once per model.
    """
    shares = len(models) if workers <= 1 and scheduler is None else 4 * workers
    groups = [[models[i] for i in share]
              for share in np.array_split(np.arange(len(models)), min(shares, len(models)))]
    outputs = run_tasks(_xrho_outputs, [(classifier, images, g) for g in groups],
                        workers, description, progress, scheduler, unit="models",
                        sizes=[len(g) for g in groups], pool=pool)
    labels = [images.dataset.label(model) for model in models]
    return (np.array(labels, dtype=np.int64),
            np.stack([o for part in outputs for o in part]).astype(np.float32))


def xrho_predictions(classifier: VocabularyTreeClassifier, images: XrhoViews,
                     models: list[ModelEntry], description: str, progress: bool = True,
                     workers: int = 1, scheduler: str | None = None,
                     pool: WorkerPool | None = None) -> tuple[np.ndarray, np.ndarray]:
    """True labels (M,) and the VP-tree's labels (M, V) on models at X_rho
    (:func:`xrho_outputs`)."""
    labels, outputs = xrho_outputs(classifier, images, models, description, progress, workers,
                                   scheduler, pool)
    return labels, outputs.argmax(axis=2)


@dataclass
class VPTreeObservation:
    """The VP-tree's observation model: ``model`` (V, C, C) the planner's and the run-time
    belief's, the ``untempered`` confusion raised to ``temperature``; ``held_out_belief`` the
    held-out calibration of the fit (:func:`~rapomdp.recognition.belief.walk_calibration`,
    empty without one) and ``note`` why t = 1 where none was fitted."""

    model: np.ndarray
    untempered: np.ndarray
    temperature: float = 1.0
    held_out_belief: dict[str, float] = field(default_factory=dict)
    note: str | None = None
    declared: DeclaredConfidence | None = None


def vptree_folds(labels: np.ndarray, predicted: np.ndarray, groups: np.ndarray, classes: int,
                 pseudo_count: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Leave-one-group-out folds of the VP-tree's confusion: each held-out group's rows (M,)
    bool and the (untempered) confusion (V, C, C) of the VP-tree's labels ``predicted``
    (M, V) of the other groups' models (true classes ``labels`` (M,), groups ``groups``)."""
    return [(held, viewpoint_confusion(labels[~held], predicted[~held], classes, pseudo_count))
            for held in held_out_groups(labels, groups)]


def vptree_observation(labels: np.ndarray, predicted: np.ndarray, groups: np.ndarray,
                       classes: int, cfg: VPTreeConfig, directions: np.ndarray,
                       rng: np.random.Generator) -> VPTreeObservation:
    """The confusion of the VP-tree's labels ``predicted`` (M, V) of models of true class
    ``labels`` (M,), tempered for a multi-view belief: t fitted on random walks over
    ``directions`` (V, 3) drawn from ``rng``, each held-out group of ``groups`` (M,) scored by
    the confusion of the others (naive Bayes over correlated views is overconfident). With
    fewer than two groups to hold out t = 1."""
    raw = viewpoint_confusion(labels, predicted, classes, cfg.pseudo_count)
    folds = vptree_folds(labels, predicted, groups, classes, cfg.pseudo_count)
    if len(folds) < 2:
        return VPTreeObservation(raw, raw, note=(
            f"t = 1: {len(folds)} held-out group(s) of volume models, two are needed (two or "
            "more volume models per class, dataset.split.volume)"))
    held = [h for h, _ in folds]
    models = [m for _, m in folds]
    row_model = fold_of_rows(held, len(labels))
    walks, walk_row = held_out_walks(row_model, directions, rng)
    t = fit_temperature(models, row_model, labels, predicted, walks, walk_row)
    report = walk_calibration(t, models, row_model, labels, predicted, walks, walk_row)
    # the declared confidence: fitted where longer held-out walks stop (as the observe stage's)
    long_walks, long_row = held_out_walks(row_model, directions, rng, DECLARED_WALK_LENGTH)
    declared = declared_confidence(
        walk_log_beliefs(t, models, row_model, predicted, long_walks, long_row),
        labels[long_row], row_model[long_row])
    return VPTreeObservation(temper(raw, t), raw, t, report, declared=declared)


def run_vptree_stage(config: Config, inputs: StageInputs, out: Path,
                     context: RunContext) -> None:
    """Fit the VP-tree, count its per-viewpoint confusion on the volume models at X_rho and
    temper it on held-out walks over them.

    Args:
        config: the run's configuration; the stage reads ``seed``, ``camera``, ``render``,
            ``viewpoints`` and ``vptree``.
        inputs: the folders of the stages it reads (dataset, render and xrho).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``vocabulary_tree.npz``, ``observation_model.npz`` (the
            per-viewpoint confusion (V, C, C), tempered), ``xrho_outputs.npz`` and ``vptree.json``.
    """
    seconds: dict[str, float] = {}
    start = time.perf_counter()
    views = load_training_views(inputs.render, inputs.dataset)
    dataset = views.dataset
    classifier = fit_vptree(views, config.vptree, config.seed, context.progress)
    seconds["fit"] = time.perf_counter() - start
    step = time.perf_counter()
    volume_models = dataset.with_role("volume")
    images = load_xrho_views(inputs.xrho, dataset)
    volume_labels, volume_pred = xrho_predictions(
        classifier, images, volume_models, "vptree: volume models at X_rho", context.progress,
        context.worker_count, context.scheduler, context.pool)
    volume_groups = class_ranks(volume_models)
    observation = vptree_observation(
        volume_labels, volume_pred, volume_groups, len(dataset.classes),
        config.vptree, fibonacci_directions(config.viewpoints.count, hemisphere=True),
        class_seed(config.seed, "vptree/temperature"))
    seconds["observation_model"] = time.perf_counter() - step
    step = time.perf_counter()
    test_models = dataset.with_role("test")
    test_accuracy = None
    test_labels = np.zeros(0, np.int64)
    test_outputs = np.zeros((0, config.viewpoints.count, len(dataset.classes)), np.float32)
    if test_models:
        test_labels, test_outputs = xrho_outputs(
            classifier, images, test_models, "vptree: test models at X_rho", context.progress,
            context.worker_count, context.scheduler, context.pool)
        test_pred = test_outputs.argmax(axis=2)
        test_accuracy = float((test_pred == test_labels[:, None]).mean())
    seconds["test"] = time.perf_counter() - step
    classifier.save(out / VPTREE_CLASSIFIER_FILE)
    save_npz(out / VPTREE_OBSERVATION_FILE, **{VPTREE_MODEL_NAME: observation.model},
             untempered=observation.untempered,
             temperature=np.array(observation.temperature),
             **({"declared_temperature": np.array(observation.declared.temperature),
                 "declared_thresholds": np.array(observation.declared.thresholds),
                 "declared_threshold_temperatures":
                     np.array(observation.declared.threshold_temperatures)}
                if observation.declared is not None else {}),
             classes=np.array(dataset.classes),
             volume_labels=volume_labels, volume_predictions=volume_pred,
             volume_groups=volume_groups)
    save_npz(out / VPTREE_OUTPUTS_FILE, xrho=test_outputs, labels=test_labels,
             models=np.array([m.id for m in test_models]),
             files=np.array([m.file for m in test_models]), classes=np.array(dataset.classes))
    seconds["total"] = time.perf_counter() - start
    write_json_atomic(out / VPTREE_SUMMARY_FILE, {
        "classes": dataset.classes,
        "train_images": int(classifier.labels.size),
        "descriptors_fit": classifier.fit_descriptors,
        "leaves": classifier.tree.leaves,
        "accuracy_test_xrho": test_accuracy,
        "accuracy_volume_xrho": float((volume_pred == volume_labels[:, None]).mean()),
        "chance": 1.0 / len(dataset.classes),
        "belief_correction": "temperature",  # the only one (docs/decisions/0003)
        "temperature": observation.temperature,
        "temperature_note": observation.note,
        "held_out_belief": observation.held_out_belief,
        "declared_confidence": (observation.declared.to_dict()
                                if observation.declared is not None else None),
        "seconds": seconds,
    })


def load_workspace_vptree(stage_dir: str | Path) -> VocabularyTreeClassifier:
    """The vptree stage's classifier (``W/vptree/vocabulary_tree.npz``)."""
    return VocabularyTreeClassifier.load(Path(stage_dir) / VPTREE_CLASSIFIER_FILE)
