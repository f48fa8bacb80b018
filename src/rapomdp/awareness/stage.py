"""The ``saliency``, ``volume`` and ``observe`` pipeline stages.

``W/saliency/``: ``maps/<class>/<model>.npz`` per volume model with ``saliency`` (views, H, W)
float16 in [0, 1] on the depth images' pixels, ``probability`` (views,) of the class on the
clean input and, for the mask, ``perturbed_probability`` (views,) after the perturbation;
``saliency.json`` (method, hyperparameters, maps per second).

``W/volume/``: ``<class>.npz`` (a :class:`~rapomdp.awareness.volume.SaliencyVolume`: ``scores``
with NaN = empty, ``counts``, ``origin``, ``voxel_size_m``, ``shape``) and ``volume.json``.

``W/observe/``: ``observation_models.npz`` with ``ra``, ``ra_class``, ``classifier`` and
``blackbox``, each
(V, C, C) = P(o | class, viewpoint) over the test viewpoints X_rho in order and the dataset's
classes in order (rows sum to 1), ``models`` (their names), ``classes``, ``scores`` (C, V)
normalised Eq. 6 scores, ``raw_scores``, ``directions`` (V, 3); ``calibration.json``;
``quality.csv|md`` (the self-awareness table); ``calibration.png``; ``timing.json``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from rapomdp.awareness.artefacts import (
    CALIBRATION_FIGURE,
    CALIBRATION_FILE,
    OBSERVATION_FILE,
    QUALITY_CSV,
    QUALITY_MD,
    SALIENCY_FILE,
    TIMING_FILE,
    VOLUME_FILE,
    saliency_map_file,
    volume_file,
)
from rapomdp.awareness.observation import (
    BlackBoxObservationModel,
    ClassifierObservationModel,
    ObservationModel,
    RAObservationModel,
    ScoreCalibration,
    calibrate_correctness,
    calibrate_per_class,
    wrong_label_distribution,
)
from rapomdp.awareness.quality import quality_table, write_quality
from rapomdp.awareness.saliency import PerturbationMask, make_attribution
from rapomdp.awareness.scores import normalise_scores, viewpoint_scores
from rapomdp.awareness.visibility import visibility_from_depth
from rapomdp.awareness.volume import SaliencyVolume, object_grid, saliency_volume
from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import TEST_STREAM, VOLUME_STREAM, xrho_renders
from rapomdp.data.training_views import load_training_views
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import load_npz, save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.progress import track
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.preprocess import input_to_image
from rapomdp.recognition.stage import TRAIN_SECTIONS, load_stage_classifier
from rapomdp.workspace import StageError

SALIENCY_SECTIONS = (*TRAIN_SECTIONS, "saliency")
VOLUME_SECTIONS = ("volume",)
OBSERVE_SECTIONS = (*TRAIN_SECTIONS, "viewpoints", "observe")


def saliency_maps(classifier: Classifier, depth_m: np.ndarray, label: int, method: str,
                  cfg: object, seed: int, batch_size: int = 128) -> dict[str, np.ndarray]:
    """2D saliency (views, H, W) of depth images w.r.t. class ``label``, on the image's pixels.

    Views are attributed ``batch_size`` at a time (the mask optimises a whole batch at once).
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


def _saliency_task(config_json: str, render_dir: str, dataset_dir: str, train_dir: str,
                   out: str, model_file: str, threads: int | None) -> tuple[int, float]:
    """One volume model's saliency maps, written to ``out``; returns (views, seconds)."""
    config = Config.model_validate_json(config_json)
    views = load_training_views(Path(render_dir), Path(dataset_dir))
    dataset = views.dataset
    model = next(m for m in dataset.models if m.file == model_file)
    classifier = load_stage_classifier(config, Path(train_dir), dataset.classes, threads)
    cfg = config.saliency
    depth, _ = views.load(model)
    start = time.perf_counter()
    seed = int(class_seed(config.seed, f"saliency/{model.id}").integers(2**31))
    result = saliency_maps(classifier, depth, dataset.label(model), cfg.method, cfg, seed,
                           cfg.batch_size)
    seconds = time.perf_counter() - start
    save_npz(Path(out) / saliency_map_file(model.class_name, model.id), compressed=True,
             saliency=result["saliency"].astype(np.float16),
             probability=result["probability"],
             perturbed_probability=result["perturbed_probability"])
    return depth.shape[0], seconds


def run_saliency_stage(config: Config, inputs: dict[str, Path], out: Path,
                       context: RunContext) -> None:
    """2D saliency maps of every class's volume model over the training viewsphere, one model
    per task over worker processes (each model has its own seed: the maps do not depend on
    the number of processes)."""
    dataset = load_dataset(inputs["dataset"])
    cfg = config.saliency
    workers = context.worker_count
    task_threads = context.in_worker().threads if workers > 1 else context.threads
    tasks = [(config.model_dump_json(), str(inputs["render"]), str(inputs["dataset"]),
              str(inputs["train"]), str(out), m.file, task_threads)
             for m in dataset.with_role("volume")]
    done = run_tasks(_saliency_task, tasks, workers, f"saliency ({cfg.method}): volume models",
                     context.progress, context.scheduler)
    total_views, seconds = sum(v for v, _ in done), sum(s for _, s in done)
    classifier = load_stage_classifier(config, inputs["train"], dataset.classes,
                                       context.threads)
    write_json_atomic(out / SALIENCY_FILE, {
        "method": cfg.method, "config": cfg.model_dump(mode="json"),
        "input_size_px": classifier.preprocessing.input_size_px,
        "views": total_views, "seconds": seconds,
        "maps_per_s": total_views / seconds if seconds > 0 else None,
        "threads": torch.get_num_threads(),
        "processes": min(workers, len(tasks)),
    })


def load_saliency(saliency_dir: Path, model: ModelEntry) -> dict[str, np.ndarray]:
    return load_npz(saliency_dir / saliency_map_file(model.class_name, model.id))


def class_volume(dataset: Dataset, views, saliency_dir: Path, class_name: str,  # noqa: ANN001
                 resolution: int) -> SaliencyVolume:
    """The saliency volume of one class from its volume model(s)' views and saliency maps."""
    models = [m for m in dataset.with_role("volume") if m.class_name == class_name]
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


def run_volume_stage(config: Config, inputs: dict[str, Path], out: Path,
                     context: RunContext) -> None:
    """One 3D dense saliency volume per class (voxel median of back-projected saliency)."""
    views = load_training_views(inputs["render"], inputs["dataset"])
    dataset = views.dataset
    start = time.perf_counter()
    info = {}
    for class_name in track(dataset.classes, "volume: classes", context.progress):
        volume = class_volume(dataset, views, inputs["saliency"], class_name,
                              config.volume.resolution)
        volume.save(out / volume_file(class_name))
        info[class_name] = {"grid": volume.grid.to_dict(),
                            "occupied_voxels": int(volume.occupied.sum()),
                            "mean_score": float(np.nanmean(volume.scores))}
    write_json_atomic(out / VOLUME_FILE, {
        "classes": dataset.classes, "resolution": config.volume.resolution,
        "seconds": time.perf_counter() - start, "volumes": info,
    })


@dataclass
class XrhoOutcomes:
    """A model's renders at X_rho and the classifier's labels there (reusable across volumes)."""

    clean: np.ndarray
    poses: np.ndarray
    predicted: np.ndarray


def xrho_outcomes(dataset: Dataset, model: ModelEntry, config: Config, classifier: Classifier,
                  purpose: str) -> XrhoOutcomes:
    clean, sensed, poses = xrho_renders(dataset, model, config, purpose)
    return XrhoOutcomes(clean, poses, classifier.predict(sensed).argmax(axis=1))


@dataclass
class Observation:
    """Everything the observe stage computes."""

    models: dict[str, ObservationModel]
    raw_scores: np.ndarray
    scores: np.ndarray
    calibration: ScoreCalibration
    volume_labels: np.ndarray
    volume_predictions: np.ndarray
    test_labels: np.ndarray
    test_predictions: np.ndarray
    quality: list[dict[str, float | str]]
    seconds: dict[str, float] = field(default_factory=dict)


def observe(config: Config, dataset: Dataset, classifier: Classifier,
            volumes: dict[str, SaliencyVolume],
            cache: dict[str, XrhoOutcomes] | None = None, progress: bool = True) -> Observation:
    """Viewpoint scores, observation models and their quality on the test models.

    ``cache`` ("class/model id" -> :class:`XrhoOutcomes`) lets callers that try several volumes (the
    voxel-resolution sweep) render and classify each model at X_rho once.
    """
    cache = {} if cache is None else cache
    classes = dataset.classes
    intrinsics = xtion_intrinsics(config.camera.width, config.camera.height)
    cfg = config.observe
    start = time.perf_counter()

    def outcomes(model: ModelEntry, purpose: str) -> XrhoOutcomes:
        key = f"{model.class_name}/{model.id}"
        if key not in cache:
            cache[key] = xrho_outcomes(dataset, model, config, classifier, purpose)
        return cache[key]

    raw = np.zeros((len(classes), config.viewpoints.count))
    vol_labels, vol_pred = [], []
    for c, class_name in enumerate(track(classes, "observe: volume models at X_rho", progress)):
        volume = volumes[class_name]
        per_model = []
        for model in (m for m in dataset.with_role("volume") if m.class_name == class_name):
            seen = outcomes(model, VOLUME_STREAM)
            vis = visibility_from_depth(seen.clean, seen.poses, intrinsics, volume.grid)
            per_model.append(viewpoint_scores(vis, volume.flat_scores()))
            vol_pred.append(seen.predicted)
            vol_labels.append(c)
        raw[c] = np.nanmean(np.stack(per_model), axis=0)
    scores_s = time.perf_counter() - start
    scores = normalise_scores(raw)
    labels, predicted = np.array(vol_labels), np.stack(vol_pred)
    correct = predicted == labels[:, None]
    calibration = calibrate_correctness(scores[labels], correct, cfg.calibration)
    wrong = wrong_label_distribution(np.broadcast_to(labels[:, None], predicted.shape),
                                     predicted, len(classes), cfg.confusion_pseudo_count)
    models: dict[str, ObservationModel] = {
        "ra": RAObservationModel(scores, calibration, wrong, classes),
        "ra_class": RAObservationModel(
            scores, calibrate_per_class(scores[labels], correct,
                                        np.broadcast_to(labels[:, None], correct.shape),
                                        len(classes)), wrong, classes),
        "classifier": ClassifierObservationModel(labels, predicted, classes,
                                                 cfg.classifier_pseudo_count),
        "blackbox": BlackBoxObservationModel(labels, predicted, classes,
                                             cfg.confusion_pseudo_count),
    }
    models_s = time.perf_counter() - start
    test_models = dataset.with_role("test")
    test_labels = np.array([dataset.label(m) for m in test_models])
    test_pred = np.stack([outcomes(m, TEST_STREAM).predicted
                          for m in track(test_models, "observe: test models at X_rho", progress)])
    rows = quality_table(models, test_labels, test_pred)
    return Observation(models, raw, scores, calibration, labels, predicted, test_labels,
                       test_pred, rows, {"scores_s": scores_s, "observation_models_s": models_s,
                                         "total_s": time.perf_counter() - start})


def run_observe_stage(config: Config, inputs: dict[str, Path], out: Path,
                      context: RunContext) -> None:
    """Viewpoint scores, the RA / Classifier / black-box observation models and their quality."""
    from rapomdp.awareness.figures import calibration_figure

    dataset = load_dataset(inputs["dataset"])
    classifier = load_stage_classifier(config, inputs["train"], dataset.classes,
                                       context.threads)
    volumes = {name: SaliencyVolume.load(inputs["volume"] / volume_file(name))
               for name in dataset.classes}
    result = observe(config, dataset, classifier, volumes, progress=context.progress)
    write_quality(result.quality, out / QUALITY_CSV, out / QUALITY_MD)
    directions = fibonacci_directions(config.viewpoints.count, hemisphere=True)
    save_npz(out / OBSERVATION_FILE,
             **{name: m.probabilities for name, m in result.models.items()},
             models=np.array(list(result.models)), classes=np.array(dataset.classes),
             scores=result.scores, raw_scores=result.raw_scores, directions=directions,
             volume_labels=result.volume_labels, volume_predictions=result.volume_predictions,
             test_labels=result.test_labels, test_predictions=result.test_predictions)
    correct = result.volume_predictions == result.volume_labels[:, None]
    write_json_atomic(out / CALIBRATION_FILE, {
        **result.calibration.to_dict(),
        "per_class": result.models["ra_class"].calibration.to_dict(),
        "volume_accuracy": float(correct.mean()),
        "pairs": int(correct.size),
    })
    calibration_figure(result.scores[result.volume_labels], correct, result.calibration,
                       out / CALIBRATION_FIGURE)
    write_json_atomic(out / TIMING_FILE, result.seconds)
