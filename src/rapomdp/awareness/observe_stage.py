"""The ``observe`` pipeline stage: viewpoint scores, the observation models fitted on held-out
evidence, and their quality.

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
from rich.console import Console

from rapomdp.awareness.artefacts import (
    CALIBRATION_FIGURE,
    CALIBRATION_FILE,
    DECLARED_PREFIX,
    DECLARED_THRESHOLD_PREFIX,
    DECLARED_THRESHOLDS,
    FIRST_VIEW_PREFIX,
    OBSERVATION_FILE,
    QUALITY_CSV,
    QUALITY_MD,
    TIMING_FILE,
    VALIDATION_CSV,
    VALIDATION_MD,
    volume_file,
)
from rapomdp.awareness.choices import held_out_choices
from rapomdp.awareness.evidence import Evidence
from rapomdp.awareness.mixture import VariantChoice
from rapomdp.awareness.observation import (
    ClassScoreCalibration,
    ObservationModel,
    ScoreCalibration,
)
from rapomdp.awareness.quality import quality_table, write_quality
from rapomdp.awareness.scores import normalise_scores, viewpoint_salient_area, viewpoint_scores
from rapomdp.awareness.shrinkage import ShrinkageChoice
from rapomdp.awareness.temperature import fit_softmax_temperature
from rapomdp.awareness.transfer import (
    DEFAULT_TRANSFER_KERNEL,
    TransferKernel,
    salient_view_similarity,
)
from rapomdp.awareness.visibility import visibility_from_depth
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.config import CameraConfig, Config, NoiseConfig, ObserveConfig, ViewpointsConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, class_ranks, load_dataset
from rapomdp.data.test_views import (
    ROLE_STREAMS,
    TEST_STREAM,
    VOLUME_STREAM,
    load_xrho_views,
    xrho_renders,
)
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.io import save_npz, write_json_atomic
from rapomdp.progress import track
from rapomdp.recognition.artefacts import load_xrho_probabilities
from rapomdp.recognition.belief import DECLARED_STOP_THRESHOLDS, DeclaredConfidence, temper
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.stage import load_stage_classifier
from rapomdp.workspace import StageError, StageInputs

#: ``calibration.json: class_shrinkage``: ``ra_class``'s class intercepts as fitted. The
#: shrinkage that ``observe.class_shrinkage`` offered was retired
#: (docs/decisions/0007-class-shrinkage.md); the record is kept so that every workspace's reads
#: alike.
CLASS_SHRINKAGE_RECORD = {"amount": 0.0, "rule": "configured",
                          "reason": "observe.class_shrinkage is 'none'",
                          "grid": [0.0, 0.25, 0.5, 0.75, 1.0], "held_out": {}}


@dataclass
class XrhoOutcomes:
    """A model's renders at X_rho and the classifier's labels there (reusable across volumes)."""

    clean: np.ndarray
    poses: np.ndarray
    predicted: np.ndarray
    probabilities: np.ndarray | None = None  # (V, C) the classifier's output


def xrho_outcomes(dataset: Dataset, model: ModelEntry, classifier: Classifier, purpose: str,
                  seed: int = 0, viewpoints: ViewpointsConfig | None = None,
                  camera: CameraConfig | None = None,
                  noise: NoiseConfig | None = None) -> XrhoOutcomes:
    """One model rendered at every test viewpoint X_rho and classified.

    Args:
        dataset: The dataset ``model`` belongs to.
        model: The model.
        classifier: The trained classifier (any with ``predict(depth (N, H, W)) -> (N, C)``).
        purpose: The noise stream (``VOLUME_STREAM``, ``TEST_STREAM``).
        seed: The configuration's ``seed`` (keys the noise stream).
        viewpoints: The ``viewpoints`` section (None: the defaults).
        camera: The ``camera`` section (None: the defaults).
        noise: The ``render.noise`` section (None: off).

    Returns:
        The clean depth images (V, H, W) in metres, the camera poses (V, 4, 4), the labels
        (V,) and the classifier's output (V, C) float32.
    """
    clean, sensed, poses = xrho_renders(dataset, model, purpose, seed, viewpoints, camera, noise)
    probabilities = classifier.predict(sensed)
    return XrhoOutcomes(clean, poses, probabilities.argmax(axis=1),
                        probabilities.astype(np.float32))


def stored_outcomes(xrho_dir: Path, classifier_eval_dir: Path, dataset: Dataset
                    ) -> Callable[[ModelEntry, str], XrhoOutcomes]:
    """A reader of the models' outcomes at X_rho as the xrho stage rendered them and the
    classifier_eval stage classified them (the images and outputs :func:`xrho_outcomes` would
    make).

    Args:
        xrho_dir: the xrho stage's folder.
        classifier_eval_dir: the classifier_eval stage's folder.
        dataset: the dataset.

    Returns:
        (model, noise stream) -> its :class:`XrhoOutcomes`; a stream other than the one the
        model's role was rendered with raises :class:`~rapomdp.workspace.StageError`.
    """
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
    """Everything the observe stage computes.

    Per-model dicts are keyed by model name (``ra``: the chosen variant's entry again).
    """

    #: The belief's models (V, C, C): the single-view models tempered by ``temperatures``.
    models: dict[str, ObservationModel]
    #: Eq. 6 scores (C, V): raw, normalised, and the normalised salient area seen.
    raw_scores: np.ndarray
    scores: np.ndarray
    area_scores: np.ndarray
    #: ``ra``'s score calibration (for the records and the calibration figure).
    calibration: ScoreCalibration | ClassScoreCalibration
    #: The volume models' true classes (N,) and labels at X_rho (N, V).
    volume_labels: np.ndarray
    volume_predictions: np.ndarray
    evidence: Evidence
    #: The test models' true classes (M,) and labels at X_rho (M, V).
    test_labels: np.ndarray
    test_predictions: np.ndarray
    #: Each single-view model's quality on the test models, and held out.
    quality: list[dict[str, float | str]]
    validation: list[dict[str, float | str]] = field(default_factory=list)
    ra_variant: str = "paper"
    temperatures: dict[str, float] = field(default_factory=dict)
    single_view: dict[str, ObservationModel] = field(default_factory=dict)
    corrections: dict[str, str] = field(default_factory=dict)
    belief_calibration: dict[str, dict[str, float]] = field(default_factory=dict)
    #: Every viewpoint score by kind (``mean``, ``area``, ``similarity``).
    score_kinds: dict[str, np.ndarray] = field(default_factory=dict)
    seconds: dict[str, float] = field(default_factory=dict)
    softmax_temperature: float = 1.0
    transfer_kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL
    transfer_kernel_grid: list[dict[str, float]] = field(default_factory=list)
    ra_choice: VariantChoice | None = None
    wrong_labels: dict[str, ShrinkageChoice] = field(default_factory=dict)
    declared: dict[str, DeclaredConfidence] = field(default_factory=dict)
    #: Each held-out group's rows and the models fitted without it (the walks' models: the
    #: temperature's and the declared confidence's).
    belief_folds: list[tuple[np.ndarray, dict[str, ObservationModel]]] = field(
        default_factory=list)

    @property
    def first_view(self) -> dict[str, ObservationModel]:
        """The model of the belief's first update, by name: the belief's model itself (every
        view, the first included, is tempered alike)."""
        return self.models


def observe(dataset: Dataset, classifier: Classifier, volumes: dict[str, SaliencyVolume],
            cfg: ObserveConfig | None = None, viewpoints: ViewpointsConfig | None = None,
            camera: CameraConfig | None = None, noise: NoiseConfig | None = None,
            seed: int = 0, cache: dict[str, XrhoOutcomes] | None = None, progress: bool = True,
            source: Callable[[ModelEntry, str], XrhoOutcomes] | None = None) -> Observation:
    """Viewpoint scores, observation models fitted on the volume models' held-out evidence,
    and their quality on the test models.

    Args:
        dataset: The dataset (its volume and test models are read).
        classifier: The trained classifier (labels the renders when ``source`` is None).
        volumes: Each class's saliency volume, by class name.
        cfg: The ``observe`` section: the calibration, pseudo-counts and RA-POMDP's model
            (None: the defaults).
        viewpoints: The ``viewpoints`` section: X_rho's count V and radius in metres (None:
            the defaults).
        camera: The ``camera`` section: the depth images' size (None: the defaults).
        noise: The ``render.noise`` section of the renders when ``source`` is None (None: off).
        seed: The configuration's ``seed`` (the noise streams, the held-out walks).
        cache: "class/model id" -> :class:`XrhoOutcomes`: lets callers that try several
            volumes (the voxel-resolution sweep) render and classify each model at X_rho once.
        progress: Show progress bars.
        source: (model, noise stream) -> its outcomes, read instead of rendering and
            classifying (the stage reads the xrho and classifier_eval stages' artefacts).

    Returns:
        The stage's :class:`Observation`: each model (V, C, C) = P(o | class, viewpoint), the
        scores (C, V), the held-out evidence and the quality rows.
    """
    cache = {} if cache is None else cache
    classes = dataset.classes
    cfg = ObserveConfig() if cfg is None else cfg
    viewpoints = ViewpointsConfig() if viewpoints is None else viewpoints
    camera = CameraConfig() if camera is None else camera
    intrinsics = xtion_intrinsics(camera.width, camera.height)
    start = time.perf_counter()

    def outcomes(model: ModelEntry, purpose: str) -> XrhoOutcomes:
        key = f"{model.class_name}/{model.id}"
        if key not in cache:
            cache[key] = (source(model, purpose) if source is not None
                          else xrho_outcomes(dataset, model, classifier, purpose, seed,
                                             viewpoints, camera, noise))
        return cache[key]

    raw = np.zeros((len(classes), viewpoints.count))
    area = np.zeros_like(raw)
    similarity = np.zeros((len(classes), viewpoints.count, viewpoints.count))
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
    # the k-th volume model of every class is group k
    evidence = Evidence(labels, predicted, np.asarray(class_ranks(vol_models), dtype=np.int64))
    scores_s = time.perf_counter() - start
    # RA-POMDP's model and the belief's temperature: chosen / fitted on held-out groups
    directions = fibonacci_directions(viewpoints.count, hemisphere=True)
    chosen = held_out_choices(evidence, scores, classes, cfg, directions, seed)
    models: dict[str, ObservationModel] = {
        name: ObservationModel(temper(m.probabilities, chosen.temperatures[name]), classes)
        for name, m in chosen.single_view.items()}
    models_s = time.perf_counter() - start
    test_models = dataset.with_role("test")
    test_labels = np.array([dataset.label(m) for m in test_models])
    test_pred = np.stack([outcomes(m, TEST_STREAM).predicted
                          for m in track(test_models, "observe: test models at X_rho", progress,
                                         unit="test models")])
    rows = quality_table(chosen.single_view, test_labels, test_pred)
    calibration = chosen.single_view["ra"].calibration  # type: ignore[attr-defined]
    return Observation(
        models, raw, scores["mean"], scores["area"], calibration, labels, predicted, evidence,
        test_labels, test_pred, rows, chosen.validation, chosen.variant, chosen.temperatures,
        chosen.single_view, chosen.corrections, chosen.belief_calibration, scores,
        {"scores_s": scores_s, "observation_models_s": models_s,
         "transfer_kernel_s": chosen.kernel_s, "total_s": time.perf_counter() - start},
        softmax_t, chosen.kernel, chosen.kernel_grid, chosen.choice, chosen.shrinkage,
        chosen.declared, chosen.belief_folds)


def observe_inputs(inputs: StageInputs, dataset: Dataset, classifier: Classifier,
                   cfg: ObserveConfig | None = None, viewpoints: ViewpointsConfig | None = None,
                   camera: CameraConfig | None = None, seed: int = 0,
                   progress: bool = True) -> Observation:
    """:func:`observe` on a workspace's stage folders (what the observe stage computes): the
    volume stage's volumes and the xrho and classifier_eval stages' outcomes at X_rho.

    Args:
        inputs: The stage folders (``volume``, ``xrho``, ``classifier_eval``).
        dataset: The workspace's dataset.
        classifier: The train stage's classifier.
        cfg: The ``observe`` section (None: the defaults).
        viewpoints: The ``viewpoints`` section the xrho stage rendered (None: the defaults).
        camera: The ``camera`` section the xrho stage rendered (None: the defaults).
        seed: The configuration's ``seed``.
        progress: Show progress bars.

    Returns:
        The stage's :class:`Observation`.
    """
    volumes = {name: SaliencyVolume.load(inputs.volume / volume_file(name))
               for name in dataset.classes}
    return observe(dataset, classifier, volumes, cfg, viewpoints, camera, seed=seed,
                   progress=progress,
                   source=stored_outcomes(inputs.xrho, inputs.classifier_eval, dataset))


def run_observe_stage(config: Config, inputs: StageInputs, out: Path,
                      context: RunContext) -> None:
    """The ``observe`` stage: viewpoint scores, the RA variants / Classifier / black-box
    observation models fitted on held-out evidence, their held-out validation and their quality
    on the test models (:func:`observe`).

    Args:
        config: the run's configuration (``observe``, ``viewpoints``, ``seed``).
        inputs: the ``dataset``, ``train``, ``xrho``, ``classifier_eval`` and ``volume``
            stage folders.
        out: the stage's folder (the files listed in this module's docstring).
        context: threads and progress bars.
    """
    from rapomdp.awareness.figures import calibration_figure, calibration_score

    dataset = load_dataset(inputs.dataset)
    classifier = load_stage_classifier(config, inputs.train, dataset.classes, context.threads)
    result = observe_inputs(inputs, dataset, classifier, config.observe, config.viewpoints,
                            config.camera, config.seed, context.progress)
    write_quality(result.quality, out / QUALITY_CSV, out / QUALITY_MD)
    if result.validation:
        write_quality(result.validation, out / VALIDATION_CSV, out / VALIDATION_MD)
    directions = fibonacci_directions(config.viewpoints.count, hemisphere=True)
    ev = result.evidence
    save_npz(out / OBSERVATION_FILE,
             **{name: m.probabilities for name, m in result.models.items()},
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
             # every row is a volume model (the cross-fitted evidence that was not is retired)
             evidence_groups=ev.groups, evidence_from_volume=np.ones(len(ev.labels), bool),
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
        # the cross-fitted evidence's level shifts (retired): none
        "level_shifts": {name: 0.0 for name in result.single_view},
        "held_out_belief": result.belief_calibration,
        "transfer_kernel": {**result.transfer_kernel.to_dict(),
                            "grid": result.transfer_kernel_grid},
        # the belief's model of one object's views: naive (Eq. 5), the only one since
        # docs/decisions/0004-nuisance-and-similarity-beliefs.md
        "belief": "naive",
        "wrong_labels": {name: c.to_dict() for name, c in result.wrong_labels.items()},
        "class_shrinkage": CLASS_SHRINKAGE_RECORD,
        "declared_confidence": {name: d.to_dict() for name, d in result.declared.items()},
        # the held-out evidence: the volume models (docs/decisions/0001-cross-fitted-evidence.md)
        "evidence": "volume",
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
    if result.ra_choice is not None and result.ra_choice.too_little_evidence:
        Console(stderr=True).print(f"observe: {result.ra_choice.reason}", highlight=False,
                                   soft_wrap=True)
