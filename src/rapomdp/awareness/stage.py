"""The ``saliency``, ``volume`` and ``observe`` pipeline stages.

``W/saliency/``: ``maps/<class>/<model>.npz`` per volume model with ``saliency`` (views, H, W)
float16 in [0, 1] on the depth images' pixels, ``probability`` (views,) of the class on the
clean input and, for the mask, ``perturbed_probability`` (views,) after the perturbation;
``saliency.json`` (method, hyperparameters, maps per second).

``W/volume/``: ``<class>.npz`` (a :class:`~rapomdp.awareness.volume.SaliencyVolume`: ``scores``
with NaN = empty, ``counts``, ``origin``, ``voxel_size_m``, ``shape``) and ``volume.json``.

``W/crossfit/``: ``outcomes.npz`` (:class:`~rapomdp.awareness.crossfit.CrossfitOutcomes`: every
training model's labels at X_rho from the fold classifier that did not train on it) and
``crossfit.json``.

``W/observe/``: ``observation_models.npz`` with ``ra`` (RA-POMDP's model, the variant
``observe.ra_model`` names), every ``ra_<variant>``, ``classifier`` and ``blackbox``, each
(V, C, C) = P(o | class, viewpoint) over the test viewpoints X_rho in order and the dataset's
classes in order (rows sum to 1; tempered by ``temperatures``), ``models`` (their names),
``classes``, ``scores`` / ``area_scores`` (C, V) normalised Eq. 6 scores, ``raw_scores``,
``view_similarity`` (C, V, V) the cosine similarity of the saliency two viewpoints see
(``ra_transfer``'s kernel), ``first_view_<name>`` (the model of the belief's first update),
``directions`` (V, 3), the held-out evidence (``evidence_*``) and the test outcomes;
``calibration.json`` (``transfer_kernel``: ``ra_transfer``'s kernel, chosen on held-out
log-likelihood, and under ``grid`` every grid kernel's); ``quality.csv|md`` (test models) and
``validation.csv|md`` (held-out); ``calibration.png``; ``timing.json``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from rich.console import Console

from rapomdp.awareness.artefacts import (
    CALIBRATION_FIGURE,
    CALIBRATION_FILE,
    DECLARED_PREFIX,
    DECLARED_THRESHOLD_PREFIX,
    DECLARED_THRESHOLDS,
    DISCOUNT_KERNEL,
    DISCOUNT_PREFIX,
    FIRST_VIEW_PREFIX,
    OBSERVATION_FILE,
    PRIOR_PREFIX,
    QUALITY_CSV,
    QUALITY_MD,
    SALIENCY_FILE,
    TIMING_FILE,
    VALIDATION_CSV,
    VALIDATION_MD,
    VOLUME_FILE,
    crossfit_epochs,
    saliency_map_file,
    volume_file,
)
from rapomdp.awareness.choices import held_out_choices
from rapomdp.awareness.crossfit import CROSSFIT_FILE, CrossfitOutcomes, crossfit_outcomes
from rapomdp.awareness.evidence import (
    DEFAULT_TRANSFER_KERNEL,
    Evidence,
    ShrinkageChoice,
    TransferKernel,
    VariantChoice,
    fit_softmax_temperature,
    salient_view_similarity,
)
from rapomdp.awareness.observation import (
    ClassScoreCalibration,
    ObservationModel,
    ScoreCalibration,
    wrong_label_distribution,
)
from rapomdp.awareness.quality import quality_table, write_quality
from rapomdp.awareness.saliency import ContrastiveMask, PerturbationMask, make_attribution
from rapomdp.awareness.scores import normalise_scores, viewpoint_salient_area, viewpoint_scores
from rapomdp.awareness.visibility import visibility_from_depth
from rapomdp.awareness.volume import SaliencyVolume, object_grid, saliency_volume
from rapomdp.config import Config
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, class_ranks, load_dataset
from rapomdp.data.splits import class_seed
from rapomdp.data.test_views import (
    CROSSFIT_STREAM,
    ROLE_STREAMS,
    TEST_STREAM,
    VOLUME_STREAM,
    load_xrho_views,
    xrho_renders,
)
from rapomdp.data.training_views import TrainingViews, load_training_views
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import load_npz, save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.progress import track
from rapomdp.recognition.artefacts import load_xrho_probabilities
from rapomdp.recognition.belief import (
    DECLARED_STOP_THRESHOLDS,
    DeclaredConfidence,
    ViewDiscount,
    temper,
)
from rapomdp.recognition.classifier import Classifier, configure_torch
from rapomdp.recognition.preprocess import input_to_image
from rapomdp.recognition.stage import load_stage_classifier
from rapomdp.workspace import StageError, StageInputs


def saliency_models(dataset: Dataset, per_class: int | None) -> list[ModelEntry]:
    """The volume models whose saliency makes the class volumes: each class's first
    ``per_class`` volume models (all with None)."""
    seen: dict[str, int] = {}
    out = []
    for model in dataset.with_role("volume"):
        seen[model.class_name] = seen.get(model.class_name, 0) + 1
        if per_class is None or seen[model.class_name] <= per_class:
            out.append(model)
    return out


def saliency_maps(classifier: Classifier, depth_m: np.ndarray, label: int, method: str,
                  cfg: object, seed: int, batch_size: int = 128,
                  against: int | None = None) -> dict[str, np.ndarray]:
    """2D saliency (views, H, W) of depth images w.r.t. class ``label``, on the image's pixels
    (with ``against``: the mask of ``label`` against that class, :class:`ContrastiveMask`).

    Views are attributed ``batch_size`` at a time (the mask optimises a whole batch at once).
    """
    depth_m = np.asarray(depth_m, dtype=np.float32)
    n, h, w = depth_m.shape
    attribution = make_attribution(method, classifier.network,
                                   classifier.preprocessing.input_size_px, cfg, seed,
                                   baseline=classifier.preprocessing.background)
    if against is not None:
        if not isinstance(attribution, PerturbationMask):
            raise ValueError(f"contrastive saliency needs the mask, not {method!r}")
        attribution = ContrastiveMask(attribution.network, attribution.params, against, seed)
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


def run_saliency_stage(config: Config, inputs: StageInputs, out: Path,
                       context: RunContext) -> None:
    """2D saliency maps of every class's volume model over the training viewsphere, one model
    per task over worker processes (each model has its own seed: the maps do not depend on
    the number of processes)."""
    dataset = load_dataset(inputs.dataset)
    cfg = config.saliency
    workers = context.worker_count
    task_threads = context.in_worker().threads if workers > 1 else context.threads
    tasks = [(config.model_dump_json(), str(inputs.render), str(inputs.dataset),
              str(inputs.train), str(out), m.file, task_threads)
             for m in saliency_models(dataset, config.volume.models_per_class)]
    done = run_tasks(_saliency_task, tasks, workers, f"saliency ({cfg.method})",
                     context.progress, context.scheduler, unit="volume models",
                     pool=context.pool)
    total_views, seconds = sum(v for v, _ in done), sum(s for _, s in done)
    classifier = load_stage_classifier(config, inputs.train, dataset.classes,
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


def class_volume(dataset: Dataset, views: TrainingViews, saliency_dir: Path, class_name: str,
                 resolution: int, per_class: int | None = None) -> SaliencyVolume:
    """The saliency volume of one class from its first ``per_class`` volume models' views and
    saliency maps (all with None)."""
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
    """One 3D dense saliency volume per class (voxel median of back-projected saliency)."""
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


@dataclass
class XrhoOutcomes:
    """A model's renders at X_rho and the classifier's labels there (reusable across volumes)."""

    clean: np.ndarray
    poses: np.ndarray
    predicted: np.ndarray
    probabilities: np.ndarray | None = None  # (V, C) the classifier's output


def xrho_outcomes(dataset: Dataset, model: ModelEntry, config: Config, classifier: Classifier,
                  purpose: str) -> XrhoOutcomes:
    clean, sensed, poses = xrho_renders(dataset, model, config, purpose)
    probabilities = classifier.predict(sensed)
    return XrhoOutcomes(clean, poses, probabilities.argmax(axis=1),
                        probabilities.astype(np.float32))


def stored_outcomes(xrho_dir: Path, classifier_eval_dir: Path, dataset: Dataset
                    ) -> Callable[[ModelEntry, str], XrhoOutcomes]:
    """A model's outcomes at X_rho as the xrho stage rendered it and the classifier_eval
    stage classified it (the same images and outputs :func:`xrho_outcomes` would make)."""
    images = load_xrho_views(xrho_dir, dataset)
    probabilities = load_xrho_probabilities(classifier_eval_dir)

    def outcomes(model: ModelEntry, purpose: str) -> XrhoOutcomes:
        if ROLE_STREAMS.get(model.role) != purpose:
            raise StageError(f"observe: {model.class_name}/{model.id} is a {model.role} model; "
                             f"the stored X_rho images were not drawn from stream '{purpose}'")
        seen = images.load(model)
        p = probabilities.of(model)
        return XrhoOutcomes(seen.clean, seen.poses, p.argmax(axis=1), p)

    return outcomes


@dataclass
class Observation:
    """Everything the observe stage computes."""

    models: dict[str, ObservationModel]
    raw_scores: np.ndarray
    scores: np.ndarray
    area_scores: np.ndarray
    calibration: ScoreCalibration | ClassScoreCalibration
    volume_labels: np.ndarray
    volume_predictions: np.ndarray
    evidence: Evidence
    test_labels: np.ndarray
    test_predictions: np.ndarray
    quality: list[dict[str, float | str]]
    validation: list[dict[str, float | str]] = field(default_factory=list)
    ra_variant: str = "paper"
    temperatures: dict[str, float] = field(default_factory=dict)
    single_view: dict[str, ObservationModel] = field(default_factory=dict)
    first_view: dict[str, ObservationModel] = field(default_factory=dict)
    corrections: dict[str, str] = field(default_factory=dict)
    levels: dict[str, float] = field(default_factory=dict)
    belief_calibration: dict[str, dict[str, float]] = field(default_factory=dict)
    score_kinds: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    softmax_temperature: float = 1.0
    transfer_kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL
    transfer_kernel_grid: list[dict[str, float]] = field(default_factory=list)
    nuisance: dict[str, dict[str, float | int]] = field(default_factory=dict)
    ra_choice: VariantChoice | None = None
    discounts: dict[str, ViewDiscount] = field(default_factory=dict)
    discount_kernel: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    wrong_labels: dict[str, ShrinkageChoice] = field(default_factory=dict)
    declared: dict[str, DeclaredConfidence] = field(default_factory=dict)
    #: Each held-out group's rows and the belief's models fitted without it (the walks'
    #: models: the temperature's and the declared confidence's).
    belief_folds: list[tuple[np.ndarray, dict[str, ObservationModel]]] = field(
        default_factory=list)
    #: ``ra_class``'s class-intercept shrinkage and why (observe.class_shrinkage).
    class_shrinkage: ShrinkageChoice | None = None


def observe(config: Config, dataset: Dataset, classifier: Classifier,
            volumes: dict[str, SaliencyVolume],
            cache: dict[str, XrhoOutcomes] | None = None,
            crossfit: CrossfitOutcomes | None = None,
            views: TrainingViews | None = None, progress: bool = True,
            source: Callable[[ModelEntry, str], XrhoOutcomes] | None = None) -> Observation:
    """Viewpoint scores, observation models and their quality on the test models.

    The models are fitted on the held-out evidence ``observe.evidence`` names: the volume
    models under ``classifier`` and/or the cross-fitted training models (``crossfit``).
    ``cache`` ("class/model id" -> :class:`XrhoOutcomes`) lets callers that try several volumes (the
    voxel-resolution sweep) render and classify each model at X_rho once; ``source`` (model,
    noise stream) -> its outcomes, when given, is read instead of rendering and classifying
    (the stage reads the xrho and classifier_eval stages' artefacts).
    """
    cache = {} if cache is None else cache
    classes = dataset.classes
    intrinsics = xtion_intrinsics(config.camera.width, config.camera.height)
    cfg = config.observe
    start = time.perf_counter()

    def outcomes(model: ModelEntry, purpose: str) -> XrhoOutcomes:
        key = f"{model.class_name}/{model.id}"
        if key not in cache:
            cache[key] = (source(model, purpose) if source is not None
                          else xrho_outcomes(dataset, model, config, classifier, purpose))
        return cache[key]

    raw = np.zeros((len(classes), config.viewpoints.count))
    area = np.zeros_like(raw)
    similarity = np.zeros((len(classes), config.viewpoints.count, config.viewpoints.count))
    vol_labels, vol_pred, vol_probabilities = [], [], []
    vol_models: list[ModelEntry] = []
    for c, class_name in enumerate(track(classes, "observe: volume models at X_rho", progress,
                                                 unit="classes")):
        volume = volumes[class_name]
        voxel_scores = volume.flat_scores()
        per_model, per_model_area, per_model_similarity = [], [], []
        for model in (m for m in dataset.with_role("volume") if m.class_name == class_name):
            seen = outcomes(model, VOLUME_STREAM)
            vis = visibility_from_depth(seen.clean, seen.poses, intrinsics, volume.grid)
            per_model.append(viewpoint_scores(vis, voxel_scores))
            per_model_area.append(viewpoint_salient_area(vis, voxel_scores))
            per_model_similarity.append(salient_view_similarity(
                vis.multiply(np.nan_to_num(voxel_scores, nan=0.0)[None])))
            vol_pred.append(seen.predicted)
            vol_probabilities.append(seen.probabilities)
            vol_labels.append(c)
            vol_models.append(model)
        raw[c] = np.nanmean(np.stack(per_model), axis=0)
        area[c] = np.mean(np.stack(per_model_area), axis=0)
        similarity[c] = np.mean(np.stack(per_model_similarity), axis=0)
    scores = {"mean": normalise_scores(raw), "area": normalise_scores(area),
              "similarity": similarity}
    labels, predicted = np.array(vol_labels), np.stack(vol_pred)
    # Static's belief is the classifier's output: its temperature, fitted on the volume models
    known = [p for p in vol_probabilities if p is not None]
    softmax_t = (fit_softmax_temperature(np.stack(known), labels)
                 if len(known) == len(vol_probabilities) else 1.0)
    evidence = observation_evidence(cfg.evidence, labels, predicted, crossfit,
                                    class_ranks(vol_models))
    if cfg.contrastive:
        if views is None:
            raise StageError("observe.contrastive needs the training renders (render stage)")
        scores["contrastive"] = contrastive_scores(config, views, classifier, evidence, cache,
                                                   progress)
    scores_s = time.perf_counter() - start
    # RA-POMDP's model and the belief's corrections: chosen / fitted on held-out groups
    directions = fibonacci_directions(config.viewpoints.count, hemisphere=True)
    chosen = held_out_choices(evidence, scores, classes, cfg, directions, config.seed)
    corrections, temperatures = chosen.corrections, chosen.temperatures
    belief_models = chosen.belief_models
    models: dict[str, ObservationModel] = {
        name: ObservationModel(temper(m.probabilities, temperatures[name]), classes, m.prior)
        for name, m in belief_models.items()}
    # the belief's first update: the single-view model when only later views are discounted
    # (after_first; with the view discount every update starts from the single-view model)
    first_view: dict[str, ObservationModel] = {
        name: (belief_models[name] if corrections[name] in ("after_first", "similarity")
               else models[name])
        for name in models}
    models_s = time.perf_counter() - start
    test_models = dataset.with_role("test")
    test_labels = np.array([dataset.label(m) for m in test_models])
    test_pred = np.stack([outcomes(m, TEST_STREAM).predicted
                          for m in track(test_models, "observe: test models at X_rho", progress,
                                         unit="test models")])
    rows = quality_table(chosen.single_view, test_labels, test_pred)
    calibration = chosen.single_view["ra"].calibration  # type: ignore[attr-defined]
    return Observation(models, raw, scores["mean"], scores["area"], calibration, labels,
                       predicted, evidence, test_labels, test_pred, rows, chosen.validation,
                       chosen.variant, temperatures, chosen.single_view, first_view,
                       corrections, chosen.levels, chosen.belief_calibration, scores,
                       {"scores_s": scores_s, "observation_models_s": models_s,
                        "transfer_kernel_s": chosen.kernel_s,
                        "total_s": time.perf_counter() - start},
                       softmax_t, chosen.kernel, chosen.kernel_grid,
                       {name: nm.to_dict() for name, nm in chosen.nuisance.items()},
                       chosen.choice, chosen.discounts, chosen.discount_kernel,
                       chosen.shrinkage, chosen.declared, chosen.belief_folds,
                       chosen.class_shrinkage)


def most_confused(evidence: Evidence, classes: int) -> np.ndarray:
    """Each class's most frequent wrong label on the held-out evidence (C,) (ties: lowest)."""
    rows = np.broadcast_to(evidence.labels[:, None], evidence.predicted.shape)
    return wrong_label_distribution(rows, evidence.predicted, classes, 0.0).argmax(axis=1)


def contrastive_scores(config: Config, views: TrainingViews, classifier: Classifier,
                       evidence: Evidence, cache: dict[str, XrhoOutcomes],
                       progress: bool = True) -> np.ndarray:
    """Normalised viewpoint scores (C, V) of contrastive volumes: each class's volume model
    attributed against its most confused class (the mask, ``saliency`` settings), fused into a
    volume as the volume stage does, seen from X_rho as Eq. 6 sees the class's volume."""
    dataset = views.dataset
    classes = dataset.classes
    intrinsics = xtion_intrinsics(config.camera.width, config.camera.height)
    against = most_confused(evidence, len(classes))
    raw = np.zeros((len(classes), config.viewpoints.count))
    for c, class_name in enumerate(track(classes, "observe: contrastive volumes", progress,
                                                 unit="classes")):
        models = [m for m in saliency_models(dataset, config.volume.models_per_class)
                  if m.class_name == class_name]
        depth, poses, maps = [], [], []
        for model in models:
            d, p = views.load(model)
            depth.append(d)
            poses.append(p)
            maps.append(saliency_maps(classifier, d, c, "mask", config.saliency, config.seed,
                                      config.saliency.batch_size, int(against[c]))["saliency"])
        meshes = [dataset.mesh(m) for m in models]
        grid = object_grid(np.min([m.bounds[0] for m in meshes], axis=0),
                           np.max([m.bounds[1] for m in meshes], axis=0),
                           config.volume.resolution)
        volume = saliency_volume(np.concatenate(depth), np.concatenate(poses),
                                 np.concatenate(maps), views.intrinsics, grid)
        per_model = []
        for model in models:
            seen = cache[f"{model.class_name}/{model.id}"]
            vis = visibility_from_depth(seen.clean, seen.poses, intrinsics, volume.grid)
            per_model.append(viewpoint_scores(vis, volume.flat_scores()))
        raw[c] = np.nanmean(np.stack(per_model), axis=0)
    return normalise_scores(raw)


def observation_evidence(kind: str, volume_labels: np.ndarray, volume_predicted: np.ndarray,
                         crossfit: CrossfitOutcomes | None,
                         volume_rank: np.ndarray | None = None) -> Evidence:
    """The held-out evidence ``observe.evidence`` names. Groups: the k-th volume model of every
    class is group k (``volume_rank``; all 0 without it), cross-fitting fold f the group after
    the volume models' last."""
    rank = (np.zeros(len(volume_labels), np.int64) if volume_rank is None
            else np.asarray(volume_rank, dtype=np.int64))
    volume = Evidence(volume_labels, volume_predicted, rank, np.ones(len(rank), dtype=bool))
    if kind == "volume":
        return volume
    if crossfit is None or len(crossfit.labels) == 0:
        raise StageError(f"observe.evidence is '{kind}' but there are no cross-fitted "
                         "outcomes: run the crossfit stage")
    folded = Evidence(crossfit.labels, crossfit.predicted,
                      crossfit.folds + int(rank.max(initial=-1)) + 1,
                      np.zeros(len(crossfit.labels), dtype=bool))
    return folded if kind == "crossfit" else Evidence.concatenate([volume, folded])


def run_crossfit_stage(config: Config, inputs: StageInputs, out: Path,
                       context: RunContext) -> None:
    """k classifiers, each labelling at X_rho the training models it did not train on (nothing
    is trained when ``observe.evidence`` is ``volume``: the paper's protocol)."""
    start = time.perf_counter()
    views = load_training_views(inputs.render, inputs.dataset)
    dataset = views.dataset
    if config.observe.evidence == "volume":
        result = CrossfitOutcomes(np.zeros(0, dtype=str), np.zeros(0, np.int64),
                                  np.zeros(0, np.int64),
                                  np.zeros((0, config.viewpoints.count), np.int64), [])
    else:
        device = configure_torch(config.train.device, context.threads)
        result = crossfit_outcomes(
            config, views, device,
            lambda m: xrho_renders(dataset, m, config, CROSSFIT_STREAM)[1],
            bar=context.progress)
    result.save(out / CROSSFIT_FILE)
    correct = result.predicted == result.labels[:, None]
    write_json_atomic(out / "crossfit.json", {
        "folds": config.observe.crossfit_folds if len(result.labels) else 0,
        "epochs": crossfit_epochs(config),
        "recipe": "full" if crossfit_epochs(config) == config.train.epochs else "short",
        "models": len(result.labels),
        "held_out_accuracy": float(correct.mean()) if correct.size else None,
        "seconds": time.perf_counter() - start,
    })


def observe_inputs(config: Config, inputs: StageInputs, dataset: Dataset,
                   threads: int | None = None, progress: bool = True) -> Observation:
    """:func:`observe` on a workspace's stage folders (what the observe stage computes)."""
    classifier = load_stage_classifier(config, inputs.train, dataset.classes, threads)
    volumes = {name: SaliencyVolume.load(inputs.volume / volume_file(name))
               for name in dataset.classes}
    crossfit = (CrossfitOutcomes.load(inputs.crossfit / CROSSFIT_FILE)
                if inputs.crossfit_dir is not None else None)
    views = (load_training_views(inputs.render, inputs.dataset)
             if inputs.render_dir is not None else None)
    return observe(config, dataset, classifier, volumes, crossfit=crossfit, views=views,
                   progress=progress,
                   source=stored_outcomes(inputs.xrho, inputs.classifier_eval, dataset))


def run_observe_stage(config: Config, inputs: StageInputs, out: Path,
                      context: RunContext) -> None:
    """Viewpoint scores, the RA variants / Classifier / black-box observation models fitted on
    held-out evidence, their held-out validation and their quality on the test models."""
    from rapomdp.awareness.figures import calibration_figure, calibration_score

    dataset = load_dataset(inputs.dataset)
    result = observe_inputs(config, inputs, dataset, context.threads, context.progress)
    write_quality(result.quality, out / QUALITY_CSV, out / QUALITY_MD)
    if result.validation:
        write_quality(result.validation, out / VALIDATION_CSV, out / VALIDATION_MD)
    directions = fibonacci_directions(config.viewpoints.count, hemisphere=True)
    ev = result.evidence
    save_npz(out / OBSERVATION_FILE,
             **{name: m.probabilities for name, m in result.models.items()},
             **{f"{PRIOR_PREFIX}{name}": m.prior for name, m in result.models.items()
                if m.prior is not None},
             **({DISCOUNT_KERNEL: result.discount_kernel} if result.discounts else {}),
             **{f"{DISCOUNT_PREFIX}{name}": d.to_array()
                for name, d in result.discounts.items()},
             **{f"{DECLARED_PREFIX}{name}": np.array(d.temperature)
                for name, d in result.declared.items()},
             **{f"{DECLARED_THRESHOLD_PREFIX}{name}": np.array(d.threshold_temperatures)
                for name, d in result.declared.items()},
             **({DECLARED_THRESHOLDS: np.array(DECLARED_STOP_THRESHOLDS)}
                if result.declared else {}),
             models=np.array(list(result.models)), classes=np.array(dataset.classes),
             temperatures=np.array([result.temperatures[n] for n in result.models]),
             **{f"{FIRST_VIEW_PREFIX}{name}": m.probabilities
                for name, m in result.first_view.items()},
             scores=result.scores, raw_scores=result.raw_scores, area_scores=result.area_scores,
             view_similarity=result.score_kinds["similarity"].astype(np.float32),
             softmax_temperature=np.array(result.softmax_temperature),
             directions=directions,
             volume_labels=result.volume_labels, volume_predictions=result.volume_predictions,
             evidence_labels=ev.labels, evidence_predictions=ev.predicted,
             evidence_groups=ev.groups, evidence_from_volume=ev.volume_mask,
             test_labels=result.test_labels, test_predictions=result.test_predictions)
    correct = ev.correct
    write_json_atomic(out / CALIBRATION_FILE, {
        "ra_model": result.ra_variant, "ra_model_configured": config.observe.ra_model,
        # the dataset's held_out_groups (the fewest volume models of any class) beside the
        # choice's own count of held-out objects per class
        **({"ra_model_choice": {**result.ra_choice.to_dict(),
                                "dataset_held_out_groups": dataset.held_out_groups}}
           if result.ra_choice else {}),
        **result.calibration.to_dict(),
        "variants": {name: m.calibration.to_dict()  # type: ignore[attr-defined]
                     for name, m in result.single_view.items() if name.startswith("ra_")},
        "temperatures": result.temperatures,
        "belief_corrections": result.corrections,
        "softmax_temperature": result.softmax_temperature,
        "level_shifts": result.levels,
        "held_out_belief": result.belief_calibration,
        "transfer_kernel": {**result.transfer_kernel.to_dict(),
                            "grid": result.transfer_kernel_grid},
        "belief": config.observe.belief,
        "wrong_labels": {name: c.to_dict() for name, c in result.wrong_labels.items()},
        **({"class_shrinkage": result.class_shrinkage.to_dict()}
           if result.class_shrinkage is not None else {}),
        "declared_confidence": {name: d.to_dict() for name, d in result.declared.items()},
        **({"view_discounts": {name: {"scale": d.scale, "redundancy": d.redundancy,
                                      "planner_temperature": result.temperatures[name]}
                               for name, d in result.discounts.items()}}
           if result.discounts else {}),
        **({"nuisance": result.nuisance} if result.nuisance else {}),
        "evidence": config.observe.evidence,
        "evidence_accuracy": float(correct.mean()),
        "volume_accuracy": float((result.volume_predictions
                                  == result.volume_labels[:, None]).mean()),
        "pairs": int(correct.size),
    })
    score = calibration_score(result.ra_variant)
    p_correct = np.diagonal(result.single_view["ra"].probabilities, axis1=1, axis2=2)  # (V, C)
    calibration_figure(result.score_kinds[score][ev.labels], correct, result.calibration,
                       out / CALIBRATION_FIGURE, predicted=p_correct.T[ev.labels],
                       variant=result.ra_variant)
    write_json_atomic(out / TIMING_FILE, result.seconds)
    if result.ra_choice is not None and result.ra_choice.rule in ("too little evidence",
                                                                  "unstable"):
        Console(stderr=True).print(f"observe: {result.ra_choice.reason}", highlight=False,
                                   soft_wrap=True)
