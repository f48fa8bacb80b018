"""The ``saliency`` and ``volume`` pipeline stages (the ``observe`` stage:
:mod:`rapomdp.awareness.observe_stage`).

``W/saliency/``: ``maps/<class>/<model>.npz`` per volume model with ``saliency`` (views, H, W)
float16 in [0, 1] on the depth images' pixels, ``probability`` (views,) of the class on the
clean input and, for the mask, ``perturbed_probability`` (views,) after the perturbation;
``saliency.json`` (the method used, hyperparameters, maps per second; when the recogniser
gives no input gradients and the black-box method replaced the configured one, also
``configured_method`` and ``method_note``).

``W/volume/``: ``<class>.npz`` (a :class:`~rapomdp.awareness.volume.SaliencyVolume`: ``scores``
with NaN = empty, ``counts``, ``origin``, ``voxel_size_m``, ``shape``) and ``volume.json``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from rich.console import Console

from rapomdp.awareness.artefacts import SALIENCY_FILE, VOLUME_FILE, saliency_map_file, volume_file
from rapomdp.awareness.saliency import (
    BLACK_BOX_METHOD,
    PerturbationMask,
    input_gradient_problem,
    make_attribution,
)
from rapomdp.awareness.volume import SaliencyVolume, object_grid, saliency_volume
from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry
from rapomdp.data.splits import class_seed
from rapomdp.data.training_views import TrainingViews, load_training_views
from rapomdp.io import load_npz, save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.progress import track
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.preprocess import input_to_image
from rapomdp.recognition.stage import load_stage_classifier
from rapomdp.workspace import StageError, StageInputs


def saliency_models(dataset: Dataset, per_class: int | None) -> list[ModelEntry]:
    """The volume models whose saliency makes the class volumes.

    Args:
        dataset: the dataset (its volume models are read, in order).
        per_class: volume models per class (``volume.models_per_class``); None: all.

    Returns:
        Each class's first ``per_class`` volume models, in the dataset's order.
    """
    seen: dict[str, int] = {}
    out = []
    for model in dataset.with_role("volume"):
        seen[model.class_name] = seen.get(model.class_name, 0) + 1
        if per_class is None or seen[model.class_name] <= per_class:
            out.append(model)
    return out


def saliency_maps(classifier: Classifier, depth_m: np.ndarray, label: int, method: str,
                  cfg: object, seed: int, batch_size: int = 128) -> dict[str, np.ndarray]:
    """2D saliency of depth images with respect to one class, on the images' pixels.

    Views are attributed ``batch_size`` at a time (the mask optimises a whole batch at once).

    Args:
        classifier: the trained classifier.
        depth_m: (views, H, W) depth images in metres (0: background).
        label: the class index attributed.
        method: the saliency method (``saliency.method``).
        cfg: the saliency section (the method's hyperparameters).
        seed: the attribution's seed (the mask's jitter).
        batch_size: views attributed together.

    Returns:
        ``saliency`` (views, H, W) in [0, 1] (0 off the object), ``probability`` (views,) of
        the class on the clean input, ``perturbed_probability`` (views,) after the mask's
        perturbation (NaN for the other methods).
    """
    depth_m = np.asarray(depth_m, dtype=np.float32)
    n, h, w = depth_m.shape
    attribution = make_attribution(method, classifier.network,
                                   classifier.preprocessing.input_size_px, cfg, seed,
                                   baseline=classifier.preprocessing.background)
    prep = classifier.preprocess(depth_m)
    maps = np.empty((n, h, w), dtype=np.float32)
    perturbed = np.full(n, np.nan, dtype=np.float32)
    for start in range(0, n, batch_size):
        part = slice(start, start + batch_size)
        inputs = torch.from_numpy(prep.images[part]).to(classifier.device)
        target = torch.full((inputs.shape[0],), label, dtype=torch.long)
        on_input = attribution.attribute(inputs, target).cpu().numpy()
        maps[part] = input_to_image(on_input, prep.boxes[part], h, w)
        if isinstance(attribution, PerturbationMask) and attribution.last_probability is not None:
            perturbed[part] = attribution.last_probability.cpu().numpy()
    maps = np.clip(np.where(depth_m > 0, maps, 0.0), 0.0, 1.0)
    probability = classifier.predict_inputs(prep.images)[:, label]
    return {"saliency": maps, "probability": probability, "perturbed_probability": perturbed}


#: Views of the first volume model on which the recogniser's input gradient is probed.
GRADIENT_PROBE_VIEWS = 8


class SaliencyMethod(NamedTuple):
    """The method the saliency stage runs (``used``), and why it is not the configured one
    (``note``: None when it is)."""

    used: str
    note: str | None


def saliency_method(classifier: Classifier, depth_m: np.ndarray, label: int,
                    method: str) -> SaliencyMethod:
    """The saliency method the stage runs: ``method``, or the black-box
    :data:`~rapomdp.awareness.saliency.BLACK_BOX_METHOD` when ``method`` follows the
    network's input gradient and the recogniser gives none on the probe views
    (:func:`~rapomdp.awareness.saliency.input_gradient_problem`), with the line that says so.

    Args:
        classifier: the trained classifier.
        depth_m: the probe views (n, H, W), depth in metres (a volume model's).
        label: their class.
        method: the configured method (``saliency.method``).

    Returns:
        The method used and, when it is not ``method``, the note saying why.
    """
    if method == BLACK_BOX_METHOD:
        return SaliencyMethod(method, None)
    inputs = torch.from_numpy(classifier.preprocess(depth_m).images).to(classifier.device)
    target = torch.full((inputs.shape[0],), label, dtype=torch.long)
    problem = input_gradient_problem(classifier.network, inputs, target)
    if problem is None:
        return SaliencyMethod(method, None)
    return SaliencyMethod(BLACK_BOX_METHOD, (
        f"saliency: the recogniser gives no input gradients ({problem}); the black-box "
        f"method {BLACK_BOX_METHOD!r} is used instead of {method!r}"))


def _saliency_task(config_json: str, render_dir: str, dataset_dir: str, train_dir: str,
                   out: str, model_file: str, threads: int | None,
                   method: str) -> tuple[int, float]:
    """One volume model's saliency maps by ``method``, written to ``out``; returns (views,
    seconds)."""
    config = Config.model_validate_json(config_json)
    views = load_training_views(Path(render_dir), Path(dataset_dir))
    dataset = views.dataset
    model = next(m for m in dataset.models if m.file == model_file)
    classifier = load_stage_classifier(config, Path(train_dir), dataset.classes, threads)
    cfg = config.saliency
    depth, _ = views.load(model)
    start = time.perf_counter()
    seed = int(class_seed(config.seed, f"saliency/{model.id}").integers(2**31))
    result = saliency_maps(classifier, depth, dataset.label(model), method, cfg, seed,
                           cfg.batch_size)
    seconds = time.perf_counter() - start
    save_npz(Path(out) / saliency_map_file(model.class_name, model.id), compressed=True,
             saliency=result["saliency"].astype(np.float16),
             probability=result["probability"],
             perturbed_probability=result["perturbed_probability"])
    return depth.shape[0], seconds


def run_saliency_stage(config: Config, inputs: StageInputs, out: Path,
                       context: RunContext) -> None:
    """The ``saliency`` stage: 2D saliency maps of every class's volume models over the
    training viewsphere, one model per task over worker processes (each model has its own
    seed, so the maps do not depend on the number of processes).

    Before any map, the recogniser's input gradient is probed on the first volume model's
    views (:func:`saliency_method`): a recogniser that gives none is attributed with the
    black-box method (``occlusion``) instead of a gradient method, one line on stderr says
    so, and ``saliency.json`` records both. The stage's key is the same either way.

    Args:
        config: the run's configuration (``saliency``, ``volume.models_per_class``).
        inputs: the ``dataset``, ``render`` and ``train`` stage folders.
        out: the stage's folder: ``maps/<class>/<model>.npz`` and ``saliency.json``.
        context: threads, worker processes and progress bars.
    """
    views = load_training_views(inputs.render, inputs.dataset)
    dataset = views.dataset
    cfg = config.saliency
    models = saliency_models(dataset, config.volume.models_per_class)
    classifier = load_stage_classifier(config, inputs.train, dataset.classes,
                                       context.threads)
    method = SaliencyMethod(cfg.method, None)
    if models:
        probe = views.load(models[0])[0][:GRADIENT_PROBE_VIEWS]
        method = saliency_method(classifier, probe, dataset.label(models[0]), cfg.method)
    if method.note is not None:
        Console(stderr=True).print(method.note, highlight=False, soft_wrap=True)
    workers = context.worker_count
    task_threads = context.in_worker().threads if workers > 1 else context.threads
    tasks = [(config.model_dump_json(), str(inputs.render), str(inputs.dataset),
              str(inputs.train), str(out), m.file, task_threads, method.used)
             for m in models]
    done = run_tasks(_saliency_task, tasks, workers, f"saliency ({method.used})",
                     context.progress, context.scheduler, unit="volume models",
                     pool=context.pool)
    total_views, seconds = sum(v for v, _ in done), sum(s for _, s in done)
    fallback = ({} if method.note is None else
                {"configured_method": cfg.method, "method_note": method.note})
    write_json_atomic(out / SALIENCY_FILE, {
        "method": method.used, **fallback, "config": cfg.model_dump(mode="json"),
        "input_size_px": classifier.preprocessing.input_size_px,
        "views": total_views, "seconds": seconds,
        "maps_per_s": total_views / seconds if seconds > 0 else None,
        "threads": torch.get_num_threads(),
        "processes": min(workers, len(tasks)),
    })


def load_saliency(saliency_dir: Path, model: ModelEntry) -> dict[str, np.ndarray]:
    """One volume model's saliency maps: ``saliency`` (views, H, W) float16 in [0, 1],
    ``probability`` and ``perturbed_probability`` (views,) (:func:`saliency_maps`)."""
    return load_npz(saliency_dir / saliency_map_file(model.class_name, model.id))


def class_volume(dataset: Dataset, views: TrainingViews, saliency_dir: Path, class_name: str,
                 resolution: int, per_class: int | None = None) -> SaliencyVolume:
    """The 3D dense saliency volume of one class: its volume models' saliency maps
    back-projected along their depth images into a voxel grid around their meshes.

    Args:
        dataset: the dataset.
        views: the training renders (depth images and camera poses).
        saliency_dir: the saliency stage's folder.
        class_name: the class.
        resolution: voxels along the grid's longest side (``volume.resolution``).
        per_class: the class's first ``per_class`` volume models (None: all).

    Returns:
        The class's :class:`~rapomdp.awareness.volume.SaliencyVolume` (voxel median; NaN:
        empty).

    Raises:
        StageError: the class has no volume model.
    """
    models = [m for m in saliency_models(dataset, per_class) if m.class_name == class_name]
    if not models:
        raise StageError(f"{dataset.root}: class '{class_name}' has no volume model")
    meshes = [dataset.mesh(m) for m in models]
    lower = np.min([mesh.bounds[0] for mesh in meshes], axis=0)
    upper = np.max([mesh.bounds[1] for mesh in meshes], axis=0)
    grid = object_grid(lower, upper, resolution)
    depth, poses, maps = [], [], []
    for model in models:
        d, p = views.load(model)
        depth.append(d)
        poses.append(p)
        maps.append(load_saliency(saliency_dir, model)["saliency"].astype(np.float32))
    return saliency_volume(np.concatenate(depth), np.concatenate(poses), np.concatenate(maps),
                           views.intrinsics, grid)


def run_volume_stage(config: Config, inputs: StageInputs, out: Path,
                     context: RunContext) -> None:
    """The ``volume`` stage: one 3D dense saliency volume per class (:func:`class_volume`).

    Args:
        config: the run's configuration (``volume``).
        inputs: the ``dataset``, ``render`` and ``saliency`` stage folders.
        out: the stage's folder: ``<class>.npz`` and ``volume.json``.
        context: progress bars.
    """
    views = load_training_views(inputs.render, inputs.dataset)
    dataset = views.dataset
    start = time.perf_counter()
    info = {}
    for class_name in track(dataset.classes, "volume", context.progress, unit="classes"):
        volume = class_volume(dataset, views, inputs.saliency, class_name,
                              config.volume.resolution, config.volume.models_per_class)
        volume.save(out / volume_file(class_name))
        info[class_name] = {"grid": volume.grid.to_dict(),
                            "occupied_voxels": int(volume.occupied.sum()),
                            "mean_score": float(np.nanmean(volume.scores))}
    write_json_atomic(out / VOLUME_FILE, {
        "classes": dataset.classes, "resolution": config.volume.resolution,
        "seconds": time.perf_counter() - start, "volumes": info,
    })


