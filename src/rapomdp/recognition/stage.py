"""The ``train`` and ``classifier_eval`` pipeline stages.

``W/train/``: ``classifier.pt`` + ``classifier.json`` (the checkpoint), ``history.csv``,
``training.png`` and ``metrics.json`` (validation accuracy, images per second, wall time).

``W/classifier_eval/``: ``metrics.json`` (accuracy over X_rho and over the whole sphere, per class,
chance), ``confusion_xrho.csv|png``, ``confusion_sphere.csv|png``, ``accuracy_hemisphere.png``
and ``probabilities.npz`` (the test models' class probabilities per view, for later stages).
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np
import torch
from rich.console import Console

from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import load_xrho_views
from rapomdp.data.training_views import TrainingViews, load_training_views
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import atomic_path, save_npz, stable_hash, write_json_atomic
from rapomdp.parallel import TaskReport, run_tasks
from rapomdp.progress import track
from rapomdp.recognition.artefacts import (
    HEMISPHERE_FIGURE,
    HISTORY_FILE,
    METRICS_FILE,
    PROBABILITIES_FILE,
    TRAIN_SECTIONS,
    TRAINING_FIGURE,
    confusion_file,
)
from rapomdp.recognition.classifier import (
    WEIGHTS_FILE,
    Classifier,
    configure_torch,
    default_threads,
)
from rapomdp.recognition.evaluation import SingleViewResult, write_confusion_csv
from rapomdp.recognition.figures import confusion_figure, hemisphere_figure, training_curves
from rapomdp.recognition.network import build_member, member_networks
from rapomdp.recognition.training import (
    History,
    collect_views,
    ensemble_classifier,
    merge_histories,
    network_spec,
    preprocess_params,
    train_classifier,
    training_backbone,
    validation_drop_note,
    validation_mask,
)
from rapomdp.workspace import StageError, StageInputs, Workspace


def _finite(value: float) -> float | None:
    """JSON has no NaN: no validation views gives null."""
    return None if np.isnan(value) else value


def train_config_hash(config: Config) -> str:
    """The hash a checkpoint carries: every configuration section that shapes the classifier."""
    return stable_hash({s: config.section(s) for s in TRAIN_SECTIONS})


def load_workspace_classifier(root: str | Path, threads: int | None = None,
                              ) -> tuple[Config, TrainingViews, Classifier]:
    """A trained workspace's configuration, training views and checked classifier.

    For scripts and notebooks that work on a workspace after ``rapomdp train``.
    """
    ws = Workspace(root)
    config = ws.config(default=Config())
    views = load_training_views(ws.require("render"), ws.require("dataset"))
    classifier = load_stage_classifier(config, ws.require("train"), views.dataset.classes,
                                       threads)
    return config, views, classifier


def load_stage_classifier(config: Config, train_dir: Path, classes: list[str],
                          threads: int | None = None) -> Classifier:
    """The train stage's classifier, checked against this configuration and class list.

    Sets PyTorch's thread count to ``threads`` (the run context's; None:
    :func:`default_threads`).
    """
    return Classifier.load(
        train_dir / WEIGHTS_FILE,
        classes=classes,
        preprocessing=preprocess_params(config.train.preprocess),
        config_hash=train_config_hash(config),
        device=config.train.device,
        threads=threads or default_threads(),
    )


def _train_members_task(config: Config, render_dir: Path, dataset_dir: Path,
                        members: list[int], threads: int, report: TaskReport,
                        ) -> tuple[list[dict[str, torch.Tensor]], History]:
    """A share of an ensemble's members, trained in a worker process on the train stage's
    views and validation split (a task of the train stage): their weights and epochs."""
    views = load_training_views(render_dir, dataset_dir)
    data = collect_views(views, "train")
    held = validation_mask(data, config.train.validation_fraction,
                           class_seed(config.train_seed, "train/validation"))
    device = configure_torch("cpu", threads)
    classifier, history = train_classifier(
        data.subset(~held), data.subset(held), views.dataset.classes, config.train,
        views.intrinsics.fx, views.intrinsics.fy, config.train_seed, device,
        config.render.noise, progress=False, members=members, report=report)
    return [n.state_dict() for n in member_networks(classifier.network)], history


def _train_members_in_tasks(config: Config, inputs: StageInputs, views: TrainingViews,
                            train_views: int, device: torch.device, context: RunContext,
                            ) -> tuple[Classifier, History]:
    """An ensemble trained a share of members per worker (each member from its own seed, as
    in one process: the members do not depend on the worker count)."""
    count = config.train.ensemble
    shares = [list(map(int, share)) for share in
              np.array_split(np.arange(count), min(count, context.worker_count))]
    classes = views.dataset.classes
    batches = config.train.epochs * -(-train_views // config.train.batch_size)
    parts = run_tasks(_train_members_task,
                      [(config, inputs.render, inputs.dataset, share,
                        context.in_worker().threads) for share in shares],
                      context.worker_count, f"train: {count} ensemble members",
                      context.progress, context.scheduler, unit="batches",
                      sizes=[len(share) * batches for share in shares], reports=True,
                      pool=context.pool)
    spec = network_spec(len(classes), config.train)
    networks = []
    for states, _ in parts:
        for state in states:
            network = build_member(spec).to(device)
            network.load_state_dict(state)
            networks.append(network)
    return (ensemble_classifier(networks, classes, config.train, views.intrinsics.fx,
                                views.intrinsics.fy, device),
            merge_histories([history for _, history in parts]))


def run_train_stage(config: Config, inputs: StageInputs, out: Path,
                    context: RunContext) -> None:
    """Train the depth classifier on the train models' training-viewsphere renders.

    Args:
        config: the run's configuration; the stage reads ``seed``, ``dataset``, ``camera``,
            ``render`` and ``train``.
        inputs: the folders of the stages it reads (dataset and render).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``classifier.pt`` and ``classifier.json`` (the weights, checked
            by SHA-256, and what they were trained with), ``history.csv``, ``metrics.json`` and
            ``training.png``.
    """
    views = load_training_views(inputs.render, inputs.dataset)
    classes = views.dataset.classes
    if len(classes) < 2:
        raise StageError(f"{inputs.dataset}: training needs at least 2 classes, got {classes}")
    if config.train.network != "alexnet":  # a recogniser that cannot be used, before any view
        build_member(network_spec(len(classes), config.train))
    data = collect_views(views, "train")
    held = validation_mask(data, config.train.validation_fraction,
                           class_seed(config.train_seed, "train/validation"))
    device = configure_torch(config.train.device, context.threads)
    start = time.perf_counter()
    val = data.subset(held)
    members = config.train.ensemble
    if members > 1 and (context.worker_count > 1 or context.uses_cluster) \
            and device.type == "cpu":
        classifier, history = _train_members_in_tasks(config, inputs, views,
                                                      int((~held).sum()), device, context)
    else:
        classifier, history = train_classifier(
            data.subset(~held), val, classes, config.train,
            views.intrinsics.fx, views.intrinsics.fy, config.train_seed, device,
            config.render.noise, progress=context.progress,
        )
    wall_s = time.perf_counter() - start
    train_images = int((~held).sum()) * config.train.epochs * members
    kept = [i for i, k in enumerate(history.kept) if k]  # each member's kept epoch
    val_accuracy = (history.val_accuracy[kept[0]] if members == 1 or not len(val) else
                    float((classifier.predict(val.depth).argmax(1) == val.labels).mean()))
    metrics = {
        "classes": classes,
        "train_images": int((~held).sum()),
        "validation_images": int(held.sum()),
        "epochs": config.train.epochs,
        "ensemble": members,
        "final_train_accuracy": float(np.mean([history.train_accuracy[i] for i in kept])),
        "final_validation_accuracy": _finite(val_accuracy),
        "member_validation_accuracy": [_finite(history.val_accuracy[i]) for i in kept],
        "keep": "last",  # the epoch whose weights a network keeps
        "kept_epochs": [history.epoch[i] for i in kept],
        "wall_s": wall_s,
        "train_images_per_s": train_images / sum(history.seconds),
        "device": str(device),
        "threads": torch.get_num_threads(),
    }
    backbone = training_backbone(config.train)
    if backbone is not None:  # a scratch network's record is as before the option
        metrics["backbone"] = {"backbone": config.train.backbone, "file": backbone.path.name,
                               "sha256": backbone.sha256}
    classifier.save(out, train_config_hash(config), extra={"training": metrics})
    rows = history.rows()
    with atomic_path(out / HISTORY_FILE) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    training_curves(rows, out / TRAINING_FIGURE)
    write_json_atomic(out / METRICS_FILE, metrics)
    note = validation_drop_note(history)
    if note is not None:
        Console(stderr=True).print(note, highlight=False, soft_wrap=True)


def _classify_models(config: Config, render_dir: Path, xrho_dir: Path, dataset_dir: Path,
                     train_dir: Path, model_files: list[str], threads: int | None,
                     progress: bool = False) -> list[tuple[np.ndarray, np.ndarray | None]]:
    """The classifier's probabilities of models at X_rho (V, C), from the xrho stage's
    images, and, for test models, over their training viewsphere (views, C), model by model
    (a task of the classifier_eval stage)."""
    views = load_training_views(render_dir, dataset_dir)
    xrho = load_xrho_views(xrho_dir, dataset_dir)
    dataset = views.dataset
    classifier = load_stage_classifier(config, train_dir, dataset.classes, threads)
    by_file = {m.file: m for m in dataset.models}
    out: list[tuple[np.ndarray, np.ndarray | None]] = []
    for model in track([by_file[f] for f in model_files], "classifier: models at X_rho",
                       progress, unit="models"):
        at_xrho = classifier.predict(xrho.load(model).sensed)
        sphere = classifier.predict(views.load(model)[0]) if model.role == "test" else None
        out.append((at_xrho, sphere))
    return out


def run_classifier_eval_stage(config: Config, inputs: StageInputs, out: Path,
                              context: RunContext) -> None:
    """Single-view accuracy of the trained classifier on the test models, and its outputs at
    X_rho on the volume and test models for later stages (classified in a few shares per
    worker process; the probabilities do not depend on it).

    Args:
        config: the run's configuration; the stage reads ``seed``, ``camera``, ``render``
            and ``viewpoints`` (its key) and ``train`` (to check the checkpoint).
        inputs: the folders of the stages it reads (dataset, render, xrho and train).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``metrics.json`` (single-view accuracy, per class and
            viewpoint), ``probabilities.npz`` (the classifier's outputs at X_rho on the volume and
            test models), the confusion tables (CSV) and figures (PNG).
    """
    views = load_training_views(inputs.render, inputs.dataset)
    dataset = views.dataset
    # loaded here first: a checkpoint that does not fit is refused before any task starts
    classifier = load_stage_classifier(config, inputs.train, dataset.classes,
                                       context.threads)
    test_models = dataset.with_role("test")
    volume_models = dataset.with_role("volume")
    labels = np.array([dataset.label(m) for m in test_models], dtype=np.int64)
    vp = config.viewpoints
    files = [m.file for m in test_models + volume_models]
    if context.worker_count <= 1 and not context.uses_cluster:
        per_model = _classify_models(config, inputs.render, inputs.xrho, inputs.dataset,
                                     inputs.train, files, context.threads, context.progress)
    else:
        shares = np.array_split(np.arange(len(files)), min(4 * context.worker_count,
                                                           max(1, len(files))))
        threads = context.in_worker().threads
        parts = run_tasks(_classify_models,
                          [(config, inputs.render, inputs.xrho, inputs.dataset, inputs.train,
                            [files[i] for i in share], threads) for share in shares],
                          context.worker_count, "classifier: models at X_rho",
                          context.progress, context.scheduler, unit="models",
                          sizes=[len(share) for share in shares], pool=context.pool)
        per_model = [result for part in parts for result in part]
    volume_xrho = [x for x, _ in per_model[len(test_models):]]
    per_model = per_model[: len(test_models)]
    xrho = [x for x, _ in per_model]
    sphere = [s for _, s in per_model if s is not None]
    results = [
        SingleViewResult("xrho", dataset.classes, np.stack(xrho), labels),
        SingleViewResult("sphere", dataset.classes, np.stack(sphere), labels),
    ]
    for result in results:
        write_confusion_csv(out / confusion_file(result.name, "csv"), result.confusion(),
                            dataset.classes)
        where = "test viewpoints X_rho" if result.name == "xrho" else "whole training sphere"
        confusion_figure(
            result.confusion(), dataset.classes,
            f"single-view confusion, {where} (accuracy {result.accuracy:.1%})",
            out / confusion_file(result.name, "png"),
        )
    on_x = results[0]
    hemisphere_figure(
        fibonacci_directions(vp.count, hemisphere=True),
        [on_x.per_view_accuracy(), on_x.per_view_true_probability()],
        ["accuracy over the test models", "mean probability of the true class"],
        f"single-view recognition per test viewpoint ({vp.count} on the hemisphere, "
        f"radius {vp.radius_m} m)",
        out / HEMISPHERE_FIGURE,
    )
    save_npz(
        out / PROBABILITIES_FILE,
        xrho=on_x.probabilities.astype(np.float32),
        sphere=results[1].probabilities.astype(np.float32),
        labels=labels,
        classes=np.array(dataset.classes),
        models=np.array([m.id for m in test_models]),
        files=np.array([m.file for m in test_models]),
        volume_xrho=(np.stack(volume_xrho).astype(np.float32) if volume_xrho
                     else np.zeros((0, vp.count, len(dataset.classes)), np.float32)),
        volume_models=np.array([m.id for m in volume_models]),
        volume_files=np.array([m.file for m in volume_models]),
        volume_labels=np.array([dataset.label(m) for m in volume_models], dtype=np.int64),
    )
    write_json_atomic(
        out / METRICS_FILE,
        {
            "xrho": on_x.summary(),
            "sphere": results[1].summary(),
            "per_view_accuracy_xrho": on_x.per_view_accuracy().tolist(),
            "checkpoint_config_hash": classifier.meta["config_hash"],
        },
    )
