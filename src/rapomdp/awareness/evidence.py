"""Fitting every observation model on held-out evidence, choosing among them on held-out data,
and the likelihood temperature that keeps a multi-view belief calibrated.

*Evidence* is the classifier's labels at X_rho on objects it did not train on: the volume models
under the trained classifier (the paper's protocol) and, when cross-fitted
(:mod:`rapomdp.awareness.crossfit`), the training models under classifiers that did not see them.
Each row belongs to a *group* (the volume models are one, each cross-fitting fold another); the
groups are the units of leave-one-group-out validation, which chooses RA-POMDP's model and fits
the temperature without the test models.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import sparse
from scipy.optimize import minimize_scalar

from rapomdp.awareness.artefacts import CALIBRATION_FILE, OBSERVATION_FILE
from rapomdp.awareness.observation import (
    BlackBoxObservationModel,
    ClassifierObservationModel,
    ClassScoreCalibration,
    MixtureObservationModel,
    ObservationModel,
    RAObservationModel,
    TransferObservationModel,
    calibrate_correctness,
    calibrate_per_class,
    ridge_logistic,
    wrong_label_distribution,
)
from rapomdp.awareness.quality import quality_from_probabilities
from rapomdp.config import ObserveConfig
from rapomdp.geometry.viewsphere import geodesic_distance_matrix
from rapomdp.io import load_npz, read_json
from rapomdp.recognition.belief import (
    DECLARED_CRITERION,
    DECLARED_WALK_LENGTH,
    DeclaredConfidence,
    ViewDiscount,
    declared_confidence,
    fit_temperature,
    fit_view_discount,
    fold_of_rows,
    held_out_groups,
    held_out_walks,
    mean_later_weight,
    walk_calibration,
    walk_log_beliefs,
)
from rapomdp.recognition.evaluation import viewpoint_label_counts

RA_VARIANTS = {
    "paper": ("mean", False),  # Eq. 6 mean saliency seen, one calibration for every class
    "class": ("mean", True),  # + one intercept per class (its difficulty), shared slope
    "area": ("area", False),  # the salient area seen (Eq. 6's sum), one calibration
    "class_area": ("area", True),  # the salient area seen + per-class intercepts
    "contrastive": ("contrastive", True),  # a class against its most confused (observe.contrastive)
    "viewpoint": ("area", True),  # + the held-out per-viewpoint evidence, stacked
    "region": ("area", True),  # + the held-out accuracy per viewpoint pooled over classes
    "transfer": ("similarity", False),  # whole rows shared by views that see the same saliency
}
"""RA variant -> (viewpoint score it calibrates, per-class intercepts?)."""
STACKED_VARIANTS = ("viewpoint", "region")
"""The RA variants whose per-viewpoint term is stacked over groups of held-out evidence (they
need two groups or more)."""

@dataclass
class Evidence:
    """Held-out outcomes: true ``labels`` (N,), the classifier's ``predicted`` labels (N, V),
    each row's ``groups`` (N,) — the units of leave-one-group-out validation (the k-th volume
    model of every class is group k; cross-fitting fold f follows them) — and ``from_volume``
    (N,): the row is a volume model under the trained classifier itself (default: group 0)."""

    labels: np.ndarray
    predicted: np.ndarray
    groups: np.ndarray
    from_volume: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.from_volume is None:
            self.from_volume = np.asarray(self.groups) == 0
        self.from_volume = np.asarray(self.from_volume, dtype=bool)

    @property
    def volume_mask(self) -> np.ndarray:
        """(N,) bool: the rows labelled by the trained classifier (the volume models)."""
        assert self.from_volume is not None
        return self.from_volume

    def subset(self, mask: np.ndarray) -> Evidence:
        return Evidence(self.labels[mask], self.predicted[mask], self.groups[mask],
                        self.volume_mask[mask])

    @property
    def correct(self) -> np.ndarray:
        return self.predicted == self.labels[:, None]

    @classmethod
    def concatenate(cls, parts: Sequence[Evidence]) -> Evidence:
        return cls(np.concatenate([p.labels for p in parts]),
                   np.concatenate([p.predicted for p in parts]),
                   np.concatenate([p.groups for p in parts]),
                   np.concatenate([p.volume_mask for p in parts]))



def recorded_evidence(observe: Mapping[str, np.ndarray]) -> Evidence:
    """The held-out evidence an observe stage's artefact (``observation_models.npz``) records:
    what a refit of its models reads."""
    return Evidence(observe["evidence_labels"], observe["evidence_predictions"],
                    observe["evidence_groups"], observe["evidence_from_volume"])


def recorded_scores(observe: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The viewpoint scores an observe stage's artefact records, keyed as
    :func:`fit_observation_models` takes them (``similarity``: the saliency similarity
    ``ra_transfer`` reads, where the artefact has it)."""
    scores = {"mean": observe["scores"], "area": observe["area_scores"]}
    if "view_similarity" in observe:
        scores["similarity"] = np.asarray(observe["view_similarity"], dtype=np.float64)
    return scores

VIEWPOINT_BANDWIDTH_DEG = 20.0
"""Kernel width over viewpoints of the per-viewpoint evidence ``ra_viewpoint`` stacks (fixed a
priori: about two neighbours' spacing on X_rho, not tuned)."""
VIEWPOINT_PRIOR = 2.0
"""Pseudo-observations of the class's accuracy added to each viewpoint's kernel count."""


def _angle_deg(directions: np.ndarray) -> np.ndarray:
    """Angles (V, V) in degrees between the viewpoints' unit ``directions`` (V, 3)."""
    return np.degrees(geodesic_distance_matrix(directions, radius_m=1.0))


def viewpoint_logit(labels: np.ndarray, predicted: np.ndarray, classes: int,
                    directions: np.ndarray, pooled: bool = False) -> np.ndarray:
    """Logit (C, V) of the classifier's accuracy at each (class, viewpoint) on the evidence,
    kernel-smoothed over neighbouring viewpoints (Gaussian in the angle), shrunk to the
    class's accuracy by :data:`VIEWPOINT_PRIOR` pseudo-observations, and centred over the
    viewpoints: it says which views are harder, the class intercepts of the models that read
    it say how hard. (Uncentred, its level would be the other groups' accuracy, which in
    leave-one-group-out stacking falls as the held-out group's rises: the fit read that as a
    falling weight, docs/awareness.md §4.2.) ``pooled``: the accuracy at each viewpoint over
    every class together (the same row for each class) — a region of viewpoints bad for all
    classes (e.g. looking straight down) is seen on every object, where one class's own
    viewpoints rest on its two or three."""
    kernel = np.exp(-0.5 * (_angle_deg(directions) / VIEWPOINT_BANDWIDTH_DEG) ** 2)  # (V, V)
    onehot = np.eye(classes)[labels]  # (N, C)
    if pooled:
        onehot = np.ones((labels.size, 1))
    right = onehot.T @ (predicted == labels[:, None]).astype(np.float64)  # (C or 1, V)
    seen = np.broadcast_to(onehot.sum(axis=0)[:, None], right.shape)
    accuracy = (right.sum(axis=1) + 0.5) / (seen.sum(axis=1) + 1.0)  # (C,)
    q = (right @ kernel.T + VIEWPOINT_PRIOR * accuracy[:, None]) / (
        seen @ kernel.T + VIEWPOINT_PRIOR)
    q = np.clip(q, 1e-3, 1 - 1e-3)
    logit = np.log(q / (1 - q))
    logit -= logit.mean(axis=1, keepdims=True)
    return np.broadcast_to(logit, (classes, directions.shape[0])).copy()


VIEWPOINT_METHOD = "logistic_score_and_viewpoint_evidence"
"""calibration.json ``method`` of ``ra_viewpoint``'s fit."""
REGION_METHOD = "logistic_score_and_region_evidence"
"""calibration.json ``method`` of ``ra_region``'s fit."""


@dataclass
class FixedCorrectness:
    """P(correct) (C, V) fitted beforehand (a calibration whose input is already used):
    ``sigmoid(a_c + b * score + e * viewpoint logit)`` for ``ra_viewpoint`` and ``ra_region``."""

    correct: np.ndarray
    intercepts: np.ndarray
    weights: np.ndarray
    method: str = VIEWPOINT_METHOD

    def __call__(self, scores: np.ndarray) -> np.ndarray:
        return np.clip(self.correct, 1e-3, 1 - 1e-3)

    def to_dict(self) -> dict[str, object]:
        return {"method": self.method, "intercepts": self.intercepts.tolist(),
                "score_weight": float(self.weights[0]),
                "viewpoint_weight": float(self.weights[1])}


def fit_viewpoint_correctness(evidence: Evidence, score: np.ndarray, classes: int,
                              directions: np.ndarray, pooled: bool = False
                              ) -> FixedCorrectness | None:
    """``ra_viewpoint`` (``ra_region`` when ``pooled``: the accuracy per viewpoint over every
    class): the saliency score and the held-out per-viewpoint evidence together.
    The weights are fitted by stacking — each group's rows see the viewpoint logit computed
    from the *other* groups only — so the evidence is never scored on itself; the final
    logit uses every group. None with a single group (nothing to stack on)."""
    groups = np.unique(evidence.groups)
    if groups.size < 2:
        return None
    features, targets, class_of = [], [], []
    for g in groups:
        held, rest = evidence.subset(evidence.groups == g), evidence.subset(evidence.groups != g)
        logit = viewpoint_logit(rest.labels, rest.predicted, classes, directions, pooled)
        rows = np.broadcast_to(held.labels[:, None], held.predicted.shape)
        features.append(np.stack([score[rows, np.arange(score.shape[1])],
                                  logit[rows, np.arange(score.shape[1])]], -1).reshape(-1, 2))
        targets.append(held.correct.ravel())
        class_of.append(rows.ravel())
    f, y, g_of = np.concatenate(features), np.concatenate(targets), np.concatenate(class_of)
    x = np.zeros((y.size, classes + 2))
    x[np.arange(y.size), g_of] = 1.0
    x[:, classes:] = f
    w = ridge_logistic(x, y.astype(np.float64), 1e-2)
    while np.any(w[classes:] < 0):  # monotone in both: drop a falling feature, refit
        x[:, classes + int(np.argmin(w[classes:]))] = 0.0
        w = ridge_logistic(x, y.astype(np.float64), 1e-2)
    final = viewpoint_logit(evidence.labels, evidence.predicted, classes, directions, pooled)
    z = w[:classes, None] + w[classes] * score + w[classes + 1] * final
    return FixedCorrectness(1.0 / (1.0 + np.exp(-z)), w[:classes].copy(), w[classes:].copy(),
                            REGION_METHOD if pooled else VIEWPOINT_METHOD)


SALIENT_VIEW_POWER = 4.0
"""Exponent on the cosine similarity of two viewpoints' seen saliency in ``ra_transfer``'s
default kernel (:data:`DEFAULT_TRANSFER_KERNEL`: the fallback when there is nothing to choose
on; the observe stage chooses per dataset, :func:`choose_transfer_kernel`)."""
TRANSFER_PRIOR = 4.0
"""Pseudo-observations of the class's viewpoint-free confusion row in each ``ra_transfer``
row of the default kernel (shrinks a viewpoint with little evidence toward the class's
confusion)."""


@dataclass(frozen=True)
class TransferKernel:
    """``ra_transfer``'s kernel: the exponent on the seen-saliency similarity, the Gaussian
    width over the viewpoint angle (degrees), the pseudo-observations of the class's confusion
    row, and ``class_prior``: the objects' worth of views of the accuracy pooled over every
    class that the class row's accuracy is shrunk toward (0: the class's own accuracy; a class
    counted on two or three objects does not transfer to the next one as well as the pooled
    accuracy does, docs/awareness.md §4.2)."""

    power: float
    bandwidth_deg: float
    prior: float
    class_prior: float = 0.0

    def to_dict(self) -> dict[str, float]:
        return {"power": self.power, "bandwidth_deg": self.bandwidth_deg, "prior": self.prior,
                "class_prior": self.class_prior}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TransferKernel:
        """The kernel of :meth:`to_dict`'s keys (other keys ignored; a record from before
        ``class_prior``: 0)."""
        return cls(float(data["power"]), float(data["bandwidth_deg"]), float(data["prior"]),
                   float(data.get("class_prior", 0.0)))


DEFAULT_TRANSFER_KERNEL = TransferKernel(SALIENT_VIEW_POWER, VIEWPOINT_BANDWIDTH_DEG,
                                         TRANSFER_PRIOR)
"""The kernel without a choice (one group of evidence): the first generation's constants."""
CLASS_PRIOR_GRID = (0.0, 1.0, 4.0, 16.0, 64.0)
"""The shrinkages of the class rows' accuracy toward the pooled one the kernel choice scores with
``observe.transfer_shrinkage`` (objects' worth of views; 0: none)."""
TRANSFER_KERNEL_GRID: tuple[TransferKernel, ...] = tuple(
    TransferKernel(power, bandwidth, prior)
    for power in (0.0, 2.0, 4.0, 8.0)
    for bandwidth in (5.0, 10.0, 20.0, 40.0)
    for prior in (1.0, 2.0, 4.0, 8.0))
"""The 64 kernels :func:`choose_transfer_kernel` scores by default (the default among them)."""
SHRUNK_TRANSFER_KERNEL_GRID: tuple[TransferKernel, ...] = tuple(
    TransferKernel(k.power, k.bandwidth_deg, k.prior, class_prior)
    for k in TRANSFER_KERNEL_GRID for class_prior in CLASS_PRIOR_GRID)
"""The 320 kernels with ``observe.transfer_shrinkage``: every kernel of
:data:`TRANSFER_KERNEL_GRID` at every class prior of :data:`CLASS_PRIOR_GRID`."""


def transfer_kernel_grid(shrinkage: bool) -> tuple[TransferKernel, ...]:
    """The grid the kernel choice scores: with the class rows' shrinkage, or without."""
    return SHRUNK_TRANSFER_KERNEL_GRID if shrinkage else TRANSFER_KERNEL_GRID


def recorded_transfer_kernel(calibration: Mapping[str, Any]) -> TransferKernel:
    """The kernel an observe stage's ``calibration.json`` records (``transfer_kernel``), or
    :data:`DEFAULT_TRANSFER_KERNEL` for a workspace from before the per-dataset choice: what a
    refit of that workspace's ``ra_transfer`` must use."""
    recorded = calibration.get("transfer_kernel")
    return TransferKernel.from_dict(recorded) if recorded else DEFAULT_TRANSFER_KERNEL


@dataclass
class RecordedObservation:
    """What an observe stage recorded, read back for a refit of its models on its held-out
    evidence (the benchmarks' held-out closed loop and walks): the artefact's ``arrays``, its
    ``calibration.json``, the ``classes``, the ``evidence``, the viewpoint ``scores``,
    ``ra_transfer``'s kernel and the RA ``variant`` it chose (``ra_<name>``)."""

    arrays: Mapping[str, np.ndarray]
    calibration: dict[str, Any]
    classes: list[str]
    evidence: Evidence
    scores: dict[str, np.ndarray]
    transfer_kernel: TransferKernel
    variant: str

    @classmethod
    def load(cls, observe_dir: str | Path) -> RecordedObservation:
        arrays = load_npz(Path(observe_dir) / OBSERVATION_FILE)
        calibration = read_json(Path(observe_dir) / CALIBRATION_FILE)
        return cls(arrays, calibration, [str(c) for c in arrays["classes"]],
                   recorded_evidence(arrays), recorded_scores(arrays),
                   recorded_transfer_kernel(calibration), f"ra_{calibration['ra_model']}")

    @property
    def class_shrinkage(self) -> float:
        """``ra_class``'s class-intercept shrinkage as the stage chose it (0 before it)."""
        return float(self.calibration.get("class_shrinkage", {}).get("amount", 0.0))

    def belief_folds(self, cfg: ObserveConfig) -> Folds:
        """The held-out folds the stage fitted its belief's corrections on, refitted from what
        it recorded (``cfg``: the observe configuration it ran with): every model fitted
        without each volume group, ``ra_class``'s class intercepts and every model's wrong
        labels shrunk by the stage's choices, and ``ra``
        the chosen variant's. A naive belief's only (the nuisance belief's folds are fitted by
        EM, a view discount's belief depends on the views taken)."""
        if cfg.belief != "naive":
            raise ValueError(f"the held-out folds are refitted for observe.belief 'naive' "
                             f"only; the stage ran with {cfg.belief!r}")
        folds = class_shrunk_folds(
            leave_one_group_out(self.evidence, self.scores, self.classes, cfg,
                                self.arrays["directions"], self.transfer_kernel),
            self.class_shrinkage)
        amounts = {name: float(choice["amount"])
                   for name, choice in self.calibration.get("wrong_labels", {}).items()}
        folds = shrunk_folds(folds, amounts)
        if self.variant == f"ra_{MIXTURE_VARIANT}":
            folds = ra_mixture_folds(self.evidence, folds, self.classes)[1]
        return [(held, {**models, "ra": models[self.variant]}) for held, models in folds]


def salient_view_similarity(seen_saliency: np.ndarray | sparse.spmatrix) -> np.ndarray:
    """Cosine similarity (V, V) of the saliency each viewpoint sees: ``seen_saliency``
    (V, voxels), dense or sparse, = visibility x voxel saliency of a class's volume (1: the
    same salient parts)."""
    f = sparse.csr_matrix(seen_saliency, dtype=np.float64)
    gram = np.asarray((f @ f.T).todense())
    norm = np.sqrt(np.diag(gram)) + 1e-12
    return np.clip(gram / norm[:, None] / norm[None, :], 0.0, 1.0)


def _class_view_counts(labels: np.ndarray, predicted: np.ndarray, classes: int) -> np.ndarray:
    """Label counts n(c, x, o) (C, V, C) of the outcomes, class-major for the per-class
    kernel product: true ``labels`` (N,), ``predicted`` (N, V)."""
    return viewpoint_label_counts(labels, predicted, classes).transpose(1, 0, 2)


def _transfer_weights(similarity: np.ndarray, angle_deg: np.ndarray, power: float,
                      bandwidth_deg: float) -> np.ndarray:
    """K_c(x, x') (C, V, V) = sim_c(x, x') ** power * exp(-(angle / bandwidth) ** 2 / 2)."""
    return np.asarray(similarity, dtype=np.float64) ** power * np.exp(
        -0.5 * (angle_deg / bandwidth_deg) ** 2)[None]


def _confusion_rows(counts: np.ndarray, pseudo_count: float,
                    class_prior: float = 0.0) -> np.ndarray:
    """Each class's viewpoint-free confusion row (C, C) from the counts (C, V, C), its accuracy
    shrunk toward the accuracy pooled over every class by ``class_prior`` objects' worth of
    views (the wrong labels keep their proportions)."""
    row = counts.sum(axis=1) + pseudo_count
    row = row / row.sum(axis=1, keepdims=True)
    if class_prior == 0.0:
        return row
    c, views = counts.shape[0], counts.shape[1]
    idx = np.arange(c)
    seen = counts.sum(axis=(1, 2))  # labels counted per class (objects x views)
    pooled = counts[idx, :, idx].sum() / max(seen.sum(), 1.0)
    weight = class_prior * views / (seen + class_prior * views)  # (C,)
    accuracy = (1.0 - weight) * row[idx, idx] + weight * pooled
    wrong = row.copy()
    wrong[idx, idx] = 0.0
    wrong /= wrong.sum(axis=1, keepdims=True)
    out = wrong * (1.0 - accuracy)[:, None]
    out[idx, idx] = accuracy
    return out


def transfer_confusion(evidence: Evidence, similarity: np.ndarray, directions: np.ndarray,
                       pseudo_count: float,
                       kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL) -> np.ndarray:
    """``ra_transfer``: P(o | c, x) (V, C, C) from the held-out labels at *every* viewpoint,
    each weighted by how alike the saliency it sees is to x's (``similarity`` (C, V, V) from
    :func:`salient_view_similarity`, raised to ``kernel.power``) and how near it is (Gaussian
    in the angle, ``kernel.bandwidth_deg``), shrunk to the class's confusion row by
    ``kernel.prior`` pseudo-observations. Views that see the same salient parts share their
    evidence — the recognition-aware prior on where the classifier errs alike."""
    c = similarity.shape[0]
    counts = _class_view_counts(evidence.labels, evidence.predicted, c)  # (C, V, O)
    weights = _transfer_weights(similarity, _angle_deg(directions), kernel.power,
                                kernel.bandwidth_deg)
    smoothed = weights @ counts  # (C, V, O)
    row = _confusion_rows(counts, pseudo_count, kernel.class_prior)
    p = (smoothed + kernel.prior * row[:, None]) / (
        smoothed.sum(axis=2, keepdims=True) + kernel.prior)
    return np.ascontiguousarray(p.transpose(1, 0, 2))


def choose_transfer_kernel(evidence: Evidence, similarity: np.ndarray, directions: np.ndarray,
                           pseudo_count: float,
                           grid: Sequence[TransferKernel] = TRANSFER_KERNEL_GRID
                           ) -> tuple[TransferKernel, list[dict[str, float]]]:
    """The kernel of ``grid`` whose :func:`transfer_confusion` has the best held-out
    log-likelihood — mean log P(observed label) over every held-out outcome, each group scored
    by the model fitted on the others (the folds of :func:`leave_one_group_out`) — and every
    kernel's held-out log-likelihood, in ``grid``'s order (ties: the first). With fewer than
    two folds: :data:`DEFAULT_TRANSFER_KERNEL` and an empty table. The smoothed counts are
    computed once per (power, bandwidth) and fold; the priors reuse them."""
    masks = held_out_groups(evidence.labels, evidence.groups)
    if len(masks) < 2:
        return DEFAULT_TRANSFER_KERNEL, []
    c = similarity.shape[0]
    angle = _angle_deg(directions)
    class_priors = sorted({k.class_prior for k in grid})
    folds = []  # (rest's counts, its rows per class prior, held-out (class, view, label))
    for held in masks:
        counts = _class_view_counts(evidence.labels[~held], evidence.predicted[~held], c)
        predicted = evidence.predicted[held]
        t = np.broadcast_to(evidence.labels[held][:, None], predicted.shape).ravel()
        x = np.broadcast_to(np.arange(predicted.shape[1])[None], predicted.shape).ravel()
        rows = {b: _confusion_rows(counts, pseudo_count, b) for b in class_priors}
        folds.append((counts, rows, (t, x, predicted.ravel())))
    outcomes = sum(idx[0].size for _, _, idx in folds)
    by_shape: dict[tuple[float, float], list[int]] = {}
    for i, k in enumerate(grid):
        by_shape.setdefault((k.power, k.bandwidth_deg), []).append(i)
    log_likelihood = np.zeros(len(grid))
    for (power, bandwidth), which in by_shape.items():
        weights = _transfer_weights(similarity, angle, power, bandwidth)
        priors = np.array([grid[i].prior for i in which])[:, None]  # (K, 1)
        shrink = [grid[i].class_prior for i in which]
        total = np.zeros(len(which))
        for counts, rows, (t, x, o) in folds:
            smoothed = weights @ counts  # (C, V, O)
            seen = smoothed.sum(axis=2)[t, x]
            row = np.stack([rows[b][t, o] for b in shrink])  # (K, M)
            p = (smoothed[t, x, o] + priors * row) / (seen + priors)  # (K, M)
            total += np.log(np.maximum(p, 1e-300)).sum(axis=1)
        log_likelihood[which] = total / outcomes
    table = [{**k.to_dict(), "held_out_log_likelihood": float(ll)}
             for k, ll in zip(grid, log_likelihood, strict=True)]
    return grid[int(np.argmax(log_likelihood))], table


def fit_observation_models(evidence: Evidence, scores: dict[str, np.ndarray],
                           classes: Sequence[str], cfg: ObserveConfig,
                           directions: np.ndarray | None = None,
                           transfer_kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL,
                           names: Collection[str] | None = None
                           ) -> dict[str, ObservationModel]:
    """Every RA variant (``ra_<variant>``), the Classifier and the black-box model, fitted on
    ``evidence`` (only those in ``names`` when given); ``scores`` holds the per-class
    normalised viewpoint scores (C, V) by kind (``mean``, ``area``) and, under
    ``similarity``, the (C, V, V) saliency similarity of the viewpoints
    (:func:`salient_view_similarity`). ``ra_viewpoint`` and ``ra_region`` need the
    viewpoints' ``directions`` and two groups of evidence, ``ra_transfer`` the directions and
    the similarity (its kernel: ``transfer_kernel``)."""
    labels, predicted = evidence.labels, evidence.predicted
    rows = np.broadcast_to(labels[:, None], predicted.shape)
    correct = predicted == rows
    wrong = wrong_label_distribution(rows, predicted, len(classes), cfg.confusion_pseudo_count)
    models: dict[str, ObservationModel] = {}

    def wanted(name: str) -> bool:
        return names is None or name in names

    for variant, (kind, per_class) in RA_VARIANTS.items():
        if kind not in scores or variant in (*STACKED_VARIANTS, "transfer") or \
                not wanted(f"ra_{variant}"):
            continue
        s = scores[kind]
        calibration = (calibrate_per_class(s[labels], correct, rows, len(classes)) if per_class
                       else calibrate_correctness(s[labels], correct, cfg.calibration))
        models[f"ra_{variant}"] = RAObservationModel(s, calibration, wrong, classes)
    if directions is not None:
        for variant in STACKED_VARIANTS:
            kind = RA_VARIANTS[variant][0]
            fused = (fit_viewpoint_correctness(evidence, scores[kind], len(classes), directions,
                                               pooled=variant == "region")
                     if wanted(f"ra_{variant}") else None)
            if fused is not None:
                models[f"ra_{variant}"] = RAObservationModel(scores[kind], fused, wrong, classes)
        if "similarity" in scores and wanted("ra_transfer"):  # (C, V, V): ra_transfer's
            models["ra_transfer"] = TransferObservationModel(
                transfer_confusion(evidence, scores["similarity"], directions,
                                   cfg.confusion_pseudo_count, transfer_kernel), classes)
    if wanted("classifier"):
        models["classifier"] = ClassifierObservationModel(labels, predicted, classes,
                                                          cfg.classifier_pseudo_count)
    if wanted("blackbox"):
        models["blackbox"] = BlackBoxObservationModel(labels, predicted, classes,
                                                      cfg.confusion_pseudo_count)
    return models


def observed_probabilities(model: np.ndarray, labels: np.ndarray, predicted: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """P(observed label) and P(correct) (N, V) under ``model`` (V, C, C) for outcomes."""
    x = np.broadcast_to(np.arange(model.shape[0])[None], predicted.shape)
    t = np.broadcast_to(labels[:, None], predicted.shape)
    return model[x, t, predicted], model[x, t, t]


def configured_transfer_kernel(evidence: Evidence, scores: dict[str, np.ndarray],
                               cfg: ObserveConfig, directions: np.ndarray | None
                               ) -> tuple[TransferKernel, list[dict[str, float]]]:
    """``ra_transfer``'s kernel as the observe stage chooses it on ``evidence``
    (:func:`choose_transfer_kernel` over ``observe.transfer_shrinkage``'s grid), and the grid's
    held-out table; the default kernel without saliency similarity or directions."""
    if "similarity" not in scores or directions is None:
        return DEFAULT_TRANSFER_KERNEL, []
    return choose_transfer_kernel(evidence, scores["similarity"], directions,
                                  cfg.confusion_pseudo_count,
                                  transfer_kernel_grid(cfg.transfer_shrinkage))


def leave_one_group_out(evidence: Evidence, scores: dict[str, np.ndarray],
                        classes: Sequence[str], cfg: ObserveConfig,
                        directions: np.ndarray | None = None,
                        transfer_kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL
                        ) -> list[tuple[np.ndarray, dict[str, ObservationModel]]]:
    """For every group whose complement still covers every class: (its rows' mask, the models
    fitted on the other groups). Empty when there is one group only."""
    return [(held, fit_observation_models(evidence.subset(~held), scores, classes, cfg,
                                          directions, transfer_kernel))
            for held in held_out_groups(evidence.labels, evidence.groups)]


def validation_quality(evidence: Evidence,
                       folds: list[tuple[np.ndarray, dict[str, ObservationModel]]]
                       ) -> list[dict[str, float | str]]:
    """Held-out quality of every model: each group scored by the models fitted without it,
    pooled (the same measures as :mod:`rapomdp.awareness.quality`)."""
    if not folds:
        return []
    rows: list[dict[str, float | str]] = []
    for name in (n for n in folds[0][1] if all(n in models for _, models in folds)):
        observed, p_correct, correct = [], [], []
        for held, models in folds:
            part = evidence.subset(held)
            o, pc = observed_probabilities(models[name].probabilities, part.labels,
                                           part.predicted)
            observed.append(o.ravel())
            p_correct.append(pc.ravel())
            correct.append(part.correct.ravel())
        rows.append({"model": name, **quality_from_probabilities(
            np.concatenate(observed), np.concatenate(p_correct), np.concatenate(correct))})
    return rows


ROBUST_RA_VARIANT = "class"
"""The RA variant ``auto`` falls back to when the held-out evidence is too small to choose, and
keeps while the best variant is not better by more than one standard error: per-class
intercepts (each class's held-out accuracy, the effect that dominates and is always estimable)
and one shared saliency slope b ≥ 0 (b = 0 is the black box's diagonal). Chosen a priori, on
its number of free parameters, not on any measurement."""
CONFIGURED_ONLY = frozenset({"region"})
"""RA variants fitted and reported but used only when configured by name, never by ``auto``:
``region`` joined ``auto`` (as its robust default) only if the held-out closed loop supported it,
and it did not (benchmarks/results/region_model_rule.md)."""
MIN_HELD_OUT_OBJECTS = 2
"""Held-out objects every class needs for ``auto`` to choose: with fewer, some class's variants
would be compared on one object or none (docs/awareness.md §4.4)."""


def held_out_object_log_likelihoods(
        evidence: Evidence, folds: list[tuple[np.ndarray, dict[str, ObservationModel]]]
) -> dict[str, np.ndarray]:
    """Every model's mean log-likelihood of each held-out object's labels (N,), the object
    scored by the models fitted without its group; NaN for rows no fold holds out."""
    names = [n for n in (folds[0][1] if folds else {}) if all(n in m for _, m in folds)]
    observed = held_out_observed_probabilities(evidence, folds, names)
    return {name: np.log(np.maximum(observed[k], 1e-300)).mean(axis=1)
            for k, name in enumerate(names)}


def held_out_observed_probabilities(evidence: Evidence, folds: Folds, names: Sequence[str]
                                    ) -> np.ndarray:
    """The probability (K, N, V) each of the K models ``names`` gives each held-out label
    (N objects, V viewpoints), the object's by the model fitted without its group; NaN for
    rows no fold holds out."""
    observed = np.full((len(names), *evidence.predicted.shape), np.nan)
    for held, models in folds:
        part = evidence.subset(held)
        for k, name in enumerate(names):
            observed[k, held] = observed_probabilities(models[name].probabilities, part.labels,
                                                       part.predicted)[0]
    return observed


MIXTURE_VARIANT = "mixture"
"""``observe.ra_model: mixture`` (the default): RA-POMDP's model is the weighted average of the
RA variants ``auto`` compares (:func:`ra_mixture_folds`); adopted by a rule on fresh held-out
objects (benchmarks/results/ra_mixture_rule_v2.md), never chosen by ``auto`` itself."""
MIXTURE_ITERATIONS = 5000
"""EM iterations at most for the mixture weights (it stops when the log-likelihood gains less
than 1e-10 per label)."""


def fit_mixture_weights(observed: np.ndarray) -> np.ndarray:
    """Simplex weights (K,) maximising Σ_m log Σ_k w_k p[k, m] for the probabilities ``observed``
    (K, M) that K models give M labels: EM, from equal weights (the problem is concave, so
    the start only sets the speed)."""
    p = np.asarray(observed, dtype=np.float64)
    if p.ndim != 2 or p.shape[0] == 0 or p.shape[1] == 0 or np.any(p <= 0):
        raise ValueError(f"mixture weights need positive probabilities (models, labels), got "
                         f"shape {p.shape}")
    w = np.full(p.shape[0], 1.0 / p.shape[0])
    last = -np.inf
    for _ in range(MIXTURE_ITERATIONS):
        mix = w @ p
        ll = float(np.log(mix).sum())
        if ll - last < 1e-10 * p.shape[1]:
            break
        last = ll
        w = (w[:, None] * p / mix).mean(axis=1)
    return w / w.sum()


def mixture_candidates(names: Collection[str]) -> list[str]:
    """The models a mixture averages: every RA variant ``auto`` compares (``ra_*``, not the
    configured-only ones nor the mixture itself)."""
    return [n for n in names if n.startswith("ra_") and n != f"ra_{MIXTURE_VARIANT}"
            and n.removeprefix("ra_") not in CONFIGURED_ONLY]


def ra_mixture_folds(evidence: Evidence, folds: Folds, classes: Sequence[str]
                     ) -> tuple[dict[str, float], Folds]:
    """``ra_mixture``'s weights on every held-out group (each group's labels scored by the
    variants fitted without it), and ``folds`` with each fold's ``ra_mixture`` added, weighted
    by the *other* groups' labels only, so no fold's mixture has seen the group it scores."""
    if len(folds) < 2:
        raise ValueError("a mixture of the RA variants is weighted on held-out groups: it "
                         "needs two groups of held-out evidence or more")
    names = mixture_candidates(folds[0][1])
    observed = held_out_observed_probabilities(evidence, folds, names)
    covered = np.logical_or.reduce([held for held, _ in folds])
    weights = fit_mixture_weights(observed[:, covered].reshape(len(names), -1))
    out = []
    for held, models in folds:
        nested = fit_mixture_weights(observed[:, covered & ~held].reshape(len(names), -1))
        mixture = MixtureObservationModel(models, dict(zip(names, nested, strict=True)), classes)
        out.append((held, {**models, f"ra_{MIXTURE_VARIANT}": mixture}))
    return dict(zip(names, (float(w) for w in weights), strict=True)), out


@dataclass
class VariantChoice:
    """RA-POMDP's model and why: ``rule`` is ``configured``, ``best`` (the best held-out
    log-likelihood, better than the robust default by more than one standard error),
    ``one standard error`` (the robust default, within one standard error of the best),
    ``too little evidence`` (the robust default: fewer than :data:`MIN_HELD_OUT_OBJECTS`
    held-out objects in some class) or ``unstable`` (the robust default: made without some
    group, the choice is the robust default, :func:`check_variant_stability`); ``held_out``: per RA
    variant its mean held-out log-likelihood per object and the standard error of its paired
    difference to the best; ``objects_per_class``: the held-out objects each class had;
    ``without_each_group``: the variant chosen without each group (by group), where checked."""

    variant: str
    rule: str
    reason: str
    best: str | None = None
    held_out: dict[str, dict[str, float]] = field(default_factory=dict)
    objects_per_class: dict[str, int] = field(default_factory=dict)
    without_each_group: dict[str, str] = field(default_factory=dict)

    @property
    def too_little_evidence(self) -> bool:
        return self.rule == "too little evidence"

    def to_dict(self) -> dict[str, Any]:
        return {"variant": self.variant, "rule": self.rule, "reason": self.reason,
                "best": self.best, "too_little_evidence": self.too_little_evidence,
                "robust_default": ROBUST_RA_VARIANT,
                "min_held_out_objects": MIN_HELD_OUT_OBJECTS, "held_out": self.held_out,
                "objects_per_class": self.objects_per_class,
                "without_each_group": self.without_each_group}


def choose_ra_variant(evidence: Evidence,
                      folds: list[tuple[np.ndarray, dict[str, ObservationModel]]],
                      configured: str, classes: Sequence[str]) -> VariantChoice:
    """RA-POMDP's model: the configured variant, with ``mixture`` the weighted average of the
    variants (:func:`ra_mixture_folds`), or with ``auto`` the one the held-out objects
    support, knowing how little they may tell. For either, too little evidence — some class
    with fewer than :data:`MIN_HELD_OUT_OBJECTS` held-out objects (no folds: none) — gives the
    robust default :data:`ROBUST_RA_VARIANT`, and says so. Otherwise ``mixture`` is kept (rule
    ``mixture``, the variants' held-out table recorded) and ``auto`` applies the
    one-standard-error rule over held-out objects: the variant of best mean held-out
    log-likelihood per object, unless the
    robust default's paired difference to it (per object, each scored by the models fitted
    without its group) is within one standard error, in which case the robust default."""
    if configured not in ("auto", MIXTURE_VARIANT):
        return VariantChoice(configured, "configured", f"observe.ra_model is '{configured}'")
    per_object = held_out_object_log_likelihoods(evidence, folds)
    covered = np.zeros(len(evidence.labels), dtype=bool)
    for held, _ in folds:
        covered |= held
    counts = np.bincount(evidence.labels[covered], minlength=len(classes))
    objects = {name: int(n) for name, n in zip(classes, counts, strict=True)}
    ra = {name.removeprefix("ra_"): ll for name, ll in per_object.items()
          if name.startswith("ra_") and name.removeprefix("ra_") not in CONFIGURED_ONLY}
    if counts.min() < MIN_HELD_OUT_OBJECTS or ROBUST_RA_VARIANT not in ra:
        short = [f"'{name}' ({n})" for name, n in objects.items() if n < MIN_HELD_OUT_OBJECTS]
        reason = (f"too little held-out evidence to choose: class {', '.join(short[:5])}"
                  f"{' and more' if len(short) > 5 else ''} has fewer than "
                  f"{MIN_HELD_OUT_OBJECTS} held-out objects; the robust default "
                  f"'{ROBUST_RA_VARIANT}'")
        return VariantChoice(ROBUST_RA_VARIANT, "too little evidence", reason, None, {}, objects)
    means = {name: float(np.nanmean(ll)) for name, ll in ra.items()}
    best = max(means, key=means.__getitem__)
    table = {}
    for name, ll in ra.items():
        d = (ll - ra[best])[covered]
        se = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
        table[name] = {"mean_log_likelihood": means[name], "difference_to_best": float(d.mean()),
                       "standard_error": se}
    if configured == MIXTURE_VARIANT:
        reason = (f"the RA variants averaged with weights fitted on the held-out labels "
                  f"({int(covered.sum())} held-out objects; '{best}' alone is the best)")
        return VariantChoice(MIXTURE_VARIANT, "mixture", reason, best, table, objects)
    robust = table[ROBUST_RA_VARIANT]
    if best == ROBUST_RA_VARIANT or robust["difference_to_best"] >= -robust["standard_error"]:
        rule = "best" if best == ROBUST_RA_VARIANT else "one standard error"
        reason = (f"'{ROBUST_RA_VARIANT}' is the best held out" if best == ROBUST_RA_VARIANT
                  else f"'{best}' is the best held out, but the robust default "
                       f"'{ROBUST_RA_VARIANT}' is within one standard error of it "
                       f"({robust['difference_to_best']:+.4f} ± {robust['standard_error']:.4f}"
                       f" per object over {int(covered.sum())} held-out objects)")
        return VariantChoice(ROBUST_RA_VARIANT, rule, reason, best, table, objects)
    reason = (f"'{best}' is better held out than the robust default '{ROBUST_RA_VARIANT}' by "
              f"{-robust['difference_to_best']:.4f} per object, more than one standard error "
              f"({robust['standard_error']:.4f}) over {int(covered.sum())} held-out objects")
    return VariantChoice(best, "best", reason, best, table, objects)


MIN_STABILITY_GROUPS = 3
"""Groups of held-out evidence :func:`check_variant_stability` needs: without one group, two
more must remain for a choice to be made at all."""


def check_variant_stability(choice: VariantChoice, evidence: Evidence,
                            scores: dict[str, np.ndarray], classes: Sequence[str],
                            cfg: ObserveConfig, directions: np.ndarray | None
                            ) -> VariantChoice:
    """``choice`` if ``auto``, made again without each group of held-out evidence, leaves the
    robust default every time; else the robust default, rule ``unstable``: the evidence against
    it rests on one group. Each choice without a group is made as the stage makes the whole
    one (its own ``ra_transfer`` kernel, its own folds, the one-standard-error rule); which
    non-default variant it picks may change (two variants may carry the same signal). A
    configured variant or the robust default is kept unchecked, and so is any choice with fewer
    than :data:`MIN_STABILITY_GROUPS` groups (none could be made without one). A group without
    which some class keeps too few held-out objects to choose (uneven volume models a class)
    checks nothing: no choice is no evidence against the pick.

    Why: on two real-CAD sets ``auto`` made on two of three volume groups picked another
    variant than on all three in 17 of 30 folds, and its picks other than the robust default
    scored worse than it on the group they had not seen; on the default and the mesh set it
    picked its whole-evidence variant in every fold (benchmarks/results/choice_stability_rule.md).
    """
    if choice.rule != "best" or choice.variant == ROBUST_RA_VARIANT:
        return choice
    masks = held_out_groups(evidence.labels, evidence.groups)
    if len(masks) < MIN_STABILITY_GROUPS:
        return choice
    without: dict[str, str] = {}
    for held in masks:
        rest = evidence.subset(~held)
        kernel, _ = configured_transfer_kernel(rest, scores, cfg, directions)
        folds = leave_one_group_out(rest, scores, classes, cfg, directions, kernel)
        made = choose_ra_variant(rest, folds, "auto", classes)
        if not made.too_little_evidence:
            without[str(int(evidence.groups[held][0]))] = made.variant
    if all(v != ROBUST_RA_VARIANT for v in without.values()):
        return replace(choice, without_each_group=without)
    short = ", ".join(g for g, v in without.items() if v == ROBUST_RA_VARIANT)
    reason = (f"'{choice.variant}' is the best held out, but made without group(s) {short}, the "
              f"choice would be the robust default: too unstable to leave it; the robust "
              f"default '{ROBUST_RA_VARIANT}'")
    return VariantChoice(ROBUST_RA_VARIANT, "unstable", reason, choice.best, choice.held_out,
                         choice.objects_per_class, without)


WRONG_LABEL_SHRINKAGES = (0.0, 0.25, 0.5, 0.75, 0.9, 1.0)
"""The amounts ``observe.wrong_labels: auto`` scores: a grid fixed before any measurement of
it, from none (the counted wrong labels) to uniform wrong labels."""


def shrink_wrong_labels(probabilities: np.ndarray, amount: float) -> np.ndarray:
    """The model (V, C, C) with each row's wrong labels mixed toward uniform by ``amount``,
    its P(correct) kept: P_a(o | c, x) = (1 - a) P(o | c, x) + a (1 - P(c | c, x)) / (C - 1)
    for o != c. Where a class's mistakes went on a few held-out objects need not be where
    another object's go (docs/awareness.md §4.7); 0 returns the model."""
    p = np.asarray(probabilities, dtype=np.float64)
    c = p.shape[-1]
    if p.ndim != 3 or p.shape[1] != c:
        raise ValueError(f"wrong labels shrink a (V, C, C) model, got shape {p.shape}")
    if not 0.0 <= amount <= 1.0:
        raise ValueError(f"a shrinkage is in [0, 1], got {amount}")
    idx = np.arange(c)
    right = p[:, idx, idx]  # (V, C)
    out = (1.0 - amount) * p + amount * ((1.0 - right) / max(c - 1, 1))[:, :, None]
    out[:, idx, idx] = right
    return out


Folds = list[tuple[np.ndarray, dict[str, ObservationModel]]]
"""Leave-one-group-out folds: each held-out group's rows (N,) bool and the models fitted
without it, by name."""


def shrunk_folds(folds: Folds, amounts: Mapping[str, float]) -> Folds:
    """``folds`` with each named model's wrong labels shrunk by its amount
    (:func:`shrink_wrong_labels`; models not in ``amounts`` as they are): the belief's
    held-out models as the observe stage fits its corrections on them."""
    return [(held, {name: (ObservationModel(shrink_wrong_labels(m.probabilities, amounts[name]),
                                            m.classes) if name in amounts else m)
                    for name, m in models.items()})
            for held, models in folds]


@dataclass
class ShrinkageChoice:
    """One model's shrinkage (of its wrong labels, or of its class intercepts) and why:
    ``rule`` is ``configured`` (none), ``best`` (the best held-out log-likelihood, better than
    none by more than one standard error), ``one standard error`` (none: the best is not
    better by more) or ``too little evidence`` (none: fewer than :data:`MIN_HELD_OUT_OBJECTS`
    held-out objects in some class); ``held_out``: per amount its mean held-out
    log-likelihood per object and its paired difference to none with the standard error;
    ``grid``: the amounts scored."""

    amount: float
    rule: str
    reason: str
    held_out: dict[str, dict[str, float]] = field(default_factory=dict)
    grid: tuple[float, ...] = WRONG_LABEL_SHRINKAGES

    def to_dict(self) -> dict[str, Any]:
        return {"amount": self.amount, "rule": self.rule, "reason": self.reason,
                "grid": list(self.grid), "held_out": self.held_out}


def choose_wrong_label_shrinkage(
        evidence: Evidence, folds: list[tuple[np.ndarray, dict[str, ObservationModel]]],
        name: str, configured: str) -> ShrinkageChoice:
    """Model ``name``'s wrong-label shrinkage (:func:`shrink_wrong_labels`): none when
    ``configured`` is ``none``; with ``auto`` the amount of :data:`WRONG_LABEL_SHRINKAGES` of
    best mean held-out log-likelihood per object (each object scored by the fold models
    fitted without its group, shrunk), kept only if it beats none by more than one standard
    error of the paired difference over held-out objects; none when some class has fewer than
    :data:`MIN_HELD_OUT_OBJECTS` held-out objects."""
    if configured == "none":
        return ShrinkageChoice(0.0, "configured", "observe.wrong_labels is 'none'")
    return _choose_amount(evidence, folds, name, WRONG_LABEL_SHRINKAGES, lambda m, a: (
        ObservationModel(shrink_wrong_labels(m.probabilities, a), m.classes)))


CLASS_SHRINKAGES = (0.0, 0.25, 0.5, 0.75, 1.0)
"""The amounts ``observe.class_shrinkage: auto`` scores, fixed before its measurement
(benchmarks/results/class_shrinkage_rule.md): from the fitted class intercepts (0) to one
intercept shared by every class (1)."""


def shrink_class_intercepts(model: ObservationModel, amount: float) -> ObservationModel:
    """``ra_class`` with its class intercepts a_c moved to a_c + amount (mean(a) − a_c): each
    class's P(correct | c, x) moved by that on the logit scale, its wrong labels' proportions
    kept (:func:`shift_level`), its calibration the shrunk one. A class's intercept is fitted as
    if its held-out views were independent; they come from a few objects whose errors gather on
    whole objects (docs/awareness.md §4.4). 0 returns the model."""
    calibration = getattr(model, "calibration", None)
    if not isinstance(calibration, ClassScoreCalibration):
        raise ValueError("class intercepts are shrunk on a per-class calibration (ra_class), "
                         f"got {type(calibration).__name__}")
    if amount == 0.0:
        return model
    a = calibration.intercepts
    shift = amount * (a.mean() - a)
    out = ObservationModel(shift_level(model.probabilities, np.broadcast_to(
        shift, model.probabilities.shape[:2])), model.classes)
    shrunk = ClassScoreCalibration(a + shift, calibration.slope)
    out.calibration = shrunk  # type: ignore[attr-defined]
    return out


def choose_class_shrinkage(evidence: Evidence, folds: Folds, configured: str
                           ) -> ShrinkageChoice:
    """``ra_class``'s class-intercept shrinkage (:func:`shrink_class_intercepts`), chosen as
    the wrong-label shrinkage is: none when ``configured`` is ``none``; with ``auto`` the amount
    of :data:`CLASS_SHRINKAGES` of best mean held-out log-likelihood per object, kept only
    beyond one standard error over none."""
    if configured == "none":
        return ShrinkageChoice(0.0, "configured", "observe.class_shrinkage is 'none'",
                               grid=CLASS_SHRINKAGES)
    return _choose_amount(evidence, folds, "ra_class", CLASS_SHRINKAGES, shrink_class_intercepts)


def class_shrunk_folds(folds: Folds, amount: float) -> Folds:
    """``folds`` with each fold's ``ra_class`` shrunk by ``amount`` (its own intercepts)."""
    if amount == 0.0:
        return folds
    return [(held, {name: (shrink_class_intercepts(m, amount) if name == "ra_class" else m)
                    for name, m in models.items()})
            for held, models in folds]


def _choose_amount(evidence: Evidence, folds: Folds, name: str, grid: tuple[float, ...],
                   transform: Callable[[ObservationModel, float], ObservationModel]
                   ) -> ShrinkageChoice:
    """The amount of ``grid`` (0 first: none) of best mean held-out log-likelihood per object
    for model ``name`` transformed by it, kept only beyond one standard error over none."""
    # the folds that fitted the model (ra_viewpoint stacks over groups: a fold left with one
    # group has none)
    folds = [(held, models) for held, models in folds if name in models]
    covered = np.zeros(len(evidence.labels), dtype=bool)
    for held, _ in folds:
        covered |= held
    classes = len(folds[0][1][name].classes) if folds else 0
    counts = np.bincount(evidence.labels[covered], minlength=classes)
    if not folds or counts.min() < MIN_HELD_OUT_OBJECTS:
        return ShrinkageChoice(0.0, "too little evidence",
                               f"too little held-out evidence to choose: some class has fewer "
                               f"than {MIN_HELD_OUT_OBJECTS} held-out objects; none", grid=grid)
    per_amount = {}
    for amount in grid:
        shrunk = [(held, {name: transform(models[name], amount)}) for held, models in folds]
        per_amount[amount] = held_out_object_log_likelihoods(evidence, shrunk)[name][covered]
    table = {}
    for amount, ll in per_amount.items():
        d = ll - per_amount[0.0]
        se = float(d.std(ddof=1) / np.sqrt(d.size)) if d.size > 1 else float("inf")
        table[f"{amount:g}"] = {"mean_log_likelihood": float(ll.mean()),
                                "difference_to_none": float(d.mean()), "standard_error": se}
    best = max(grid, key=lambda a: per_amount[a].mean())
    row = table[f"{best:g}"]
    if best == 0.0:
        return ShrinkageChoice(0.0, "best", "none is the best held out", table, grid)
    if row["difference_to_none"] <= row["standard_error"]:
        return ShrinkageChoice(0.0, "one standard error",
                               f"{best:g} is the best held out, but not better than none by "
                               f"more than one standard error ({row['difference_to_none']:+.4f}"
                               f" ± {row['standard_error']:.4f} per object over "
                               f"{int(covered.sum())} held-out objects)", table, grid)
    return ShrinkageChoice(best, "best",
                           f"{best:g} is better held out than none by "
                           f"{row['difference_to_none']:.4f} per object, more than one standard "
                           f"error ({row['standard_error']:.4f}) over {int(covered.sum())} "
                           "held-out objects", table, grid)


def choose_belief_correction(report: dict[str, float], configured: str) -> str:
    """The configured belief correction, or with ``auto`` the one of least held-out belief log
    loss on the walks of :func:`held_out_temperatures` (``report``: one model's row, the
    ``after_first`` fit's keys prefixed ``after_first_``)."""
    if configured != "auto":
        return configured
    losses = {"none": report["log_loss_naive"], "temperature": report["log_loss_tempered"],
              "after_first": report["after_first_log_loss_tempered"]}
    return min(losses, key=losses.__getitem__)


def fit_softmax_temperature(probabilities: np.ndarray, labels: np.ndarray,
                            bounds: tuple[float, float] = (0.05, 20.0)) -> float:
    """The temperature T of the classifier's output p ** (1 / T) (renormalised) that maximises
    the likelihood of the true classes ``labels`` (N,) on held-out outputs ``probabilities``
    (N, V, C) or (N, C): temperature scaling of the logits, the passive belief's calibration
    (T > 1: the output was overconfident)."""
    p = np.asarray(probabilities, dtype=np.float64)
    log_p = np.log(np.maximum(p.reshape(-1, p.shape[-1]), 1e-300))
    rows = np.broadcast_to(np.asarray(labels).reshape((-1,) + (1,) * (p.ndim - 2)),
                           p.shape[:-1]).reshape(-1)

    def loss(t: float) -> float:
        z = log_p / t
        z = z - z.max(axis=1, keepdims=True)
        return float(np.mean(np.log(np.exp(z).sum(axis=1)) - z[np.arange(len(rows)), rows]))

    return float(minimize_scalar(loss, bounds=bounds, method="bounded",
                                 options={"xatol": 1e-4}).x)


# -- the classifier's level ----------------------------------------------------------------

def shift_level(probabilities: np.ndarray, shift: float | np.ndarray) -> np.ndarray:
    """The model with P(correct | c, x) moved by ``shift`` on the logit scale — one number, one
    per viewpoint (V,), or one per viewpoint and class (V, C) — and the wrong labels rescaled to
    the rest (their proportions kept). 0 returns the model."""
    p = np.asarray(probabilities, dtype=np.float64)
    by_view = np.asarray(shift, dtype=np.float64)
    if not np.any(by_view):
        return p.copy()
    idx = np.arange(p.shape[1])
    right = np.clip(p[:, idx, idx], 1e-12, 1 - 1e-12)  # (V, C)
    offset = by_view if by_view.ndim == 2 else by_view.reshape(-1, 1)
    moved = 1.0 / (1.0 + np.exp(-(np.log(right / (1 - right)) + offset)))
    out = p * ((1.0 - moved) / (1.0 - right))[:, :, None]
    out[:, idx, idx] = moved
    return out


def fit_level(probabilities: np.ndarray, labels: np.ndarray, predicted: np.ndarray,
              bound: float = 6.0) -> float:
    """The logit shift of P(correct) that maximises the likelihood of whether the classifier
    was right on ``labels`` / ``predicted`` (the modelled classifier's own held-out objects)."""
    idx = np.arange(probabilities.shape[1])
    right = np.clip(probabilities[:, idx, idx], 1e-12, 1 - 1e-12)
    x = np.broadcast_to(np.arange(right.shape[0])[None], predicted.shape)
    z = np.log(right / (1 - right))[x, np.broadcast_to(labels[:, None], predicted.shape)]
    y = (predicted == labels[:, None]).astype(np.float64)

    def loss(shift: float) -> float:
        return float(np.sum(np.logaddexp(0.0, -(z + shift)) * y
                            + np.logaddexp(0.0, z + shift) * (1 - y)))

    return float(minimize_scalar(loss, bounds=(-bound, bound), method="bounded",
                                 options={"xatol": 1e-4}).x)


# -- the belief's temperature ----------------------------------------------------------------

def view_similarity_kernel(similarity: np.ndarray, directions: np.ndarray,
                           kernel: TransferKernel) -> np.ndarray:
    """How alike two viewpoints' evidence is (V, V), 1 on the diagonal: ``ra_transfer``'s
    kernel K_c(x, x') (seen-saliency similarity ** power x Gaussian in the angle) averaged over
    the classes — what the view discount (``observe.belief: similarity``) reads."""
    weights = _transfer_weights(similarity, _angle_deg(directions), kernel.power,
                                kernel.bandwidth_deg).mean(axis=0)
    out = np.clip(weights, 0.0, 1.0)
    np.fill_diagonal(out, 1.0)
    return out


def held_out_view_discounts(evidence: Evidence,
                            folds: list[tuple[np.ndarray, dict[str, ObservationModel]]],
                            directions: np.ndarray, similarity: np.ndarray, length: int,
                            starts_per_row: int, neighbours: int, rng: np.random.Generator,
                            jump: float = 0.0
                            ) -> tuple[dict[str, ViewDiscount], dict[str, float]]:
    """Per model, the view discount fitted on random walks over the held-out groups' outcomes
    (with ``jump`` 0 the walks :func:`held_out_temperatures` draws with the same ``rng``; with
    ``jump`` > 0 some steps go anywhere, so far views are seen too), each group's beliefs
    updated by the models fitted without it, and the planner's stand-in temperature: the mean
    weight of the views after the first on those walks."""
    row_model = fold_of_rows([held for held, _ in folds], len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, directions, rng, length, starts_per_row,
                                     neighbours, jump)
    discounts, stand_ins = {}, {}
    for name in (n for n in folds[0][1] if all(n in m for _, m in folds)):
        models = [m[name].probabilities for _, m in folds]
        priors = ([m[name].prior for _, m in folds]
                  if all(m[name].prior is not None for _, m in folds) else None)
        discounts[name] = fit_view_discount(similarity, models, row_model, evidence.labels,
                                            evidence.predicted, walks, walk_row, priors)
        stand_ins[name] = mean_later_weight(discounts[name], similarity, walks)
    return discounts, stand_ins


def held_out_temperatures(evidence: Evidence,
                          folds: list[tuple[np.ndarray, dict[str, ObservationModel]]],
                          directions: np.ndarray, length: int, starts_per_row: int,
                          neighbours: int, rng: np.random.Generator,
                          after_first: bool = False
                          ) -> tuple[dict[str, float], dict[str, dict[str, float]]]:
    """One temperature per model, fitted on random walks over the held-out groups' outcomes,
    each group's beliefs updated by the models fitted without it (``after_first``: the first
    view counts in full, the fit tempers the later ones); and, per model, the calibration of
    those held-out beliefs (max belief against a right argmax) after the first and the last
    step, naive (t = 1) and tempered, with the held-out log loss of each
    (:func:`~rapomdp.recognition.belief.walk_calibration`). Empty without folds. A typed fold
    model (``observe.belief: nuisance``) walks from its prior over (type, class)."""
    if not folds:
        return {}, {}
    row_model = fold_of_rows([held for held, _ in folds], len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, directions, rng, length, starts_per_row,
                                     neighbours)
    temperatures, calibration = {}, {}
    for name in (n for n in folds[0][1] if all(n in m for _, m in folds)):
        models = [m[name].probabilities for _, m in folds]
        priors = ([m[name].prior for _, m in folds]
                  if all(m[name].prior is not None for _, m in folds) else None)
        first = 1.0 if after_first else None
        t = fit_temperature(models, row_model, evidence.labels, evidence.predicted, walks,
                            walk_row, first_temperature=first, priors=priors)
        temperatures[name] = t
        calibration[name] = walk_calibration(t, models, row_model, evidence.labels,
                                             evidence.predicted, walks, walk_row, first,
                                             priors)
    return temperatures, calibration


def held_out_declared_confidence(evidence: Evidence,
                                 folds: list[tuple[np.ndarray, dict[str, ObservationModel]]],
                                 temperatures: Mapping[str, float],
                                 corrections: Mapping[str, str], directions: np.ndarray,
                                 starts_per_row: int, neighbours: int,
                                 rng: np.random.Generator,
                                 criterion: str = DECLARED_CRITERION
                                 ) -> dict[str, DeclaredConfidence]:
    """Per model, the declared confidence fitted where held-out walks stop
    (:func:`~rapomdp.recognition.belief.declared_confidence`): each group's walks of
    ``DECLARED_WALK_LENGTH`` views updated by the models fitted without it, with the belief's
    own correction (``temperatures``; ``after_first``: the first view in full). A view
    discount's belief (``similarity``) depends on the views taken and is not fitted here.
    ``criterion``: what a minimises (:data:`~rapomdp.recognition.belief.DECLARED_CRITERIA`).
    Empty without folds."""
    if not folds:
        return {}
    row_model = fold_of_rows([held for held, _ in folds], len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, directions, rng, DECLARED_WALK_LENGTH,
                                     starts_per_row, neighbours)
    fitted: dict[str, DeclaredConfidence] = {}
    for name in (n for n in folds[0][1] if all(n in m for _, m in folds)):
        correction = corrections.get(name, "none")
        if correction == "similarity":
            continue
        models = [m[name].probabilities for _, m in folds]
        priors = ([m[name].prior for _, m in folds]
                  if all(m[name].prior is not None for _, m in folds) else None)
        log_beliefs = walk_log_beliefs(
            temperatures.get(name, 1.0), models, row_model, evidence.predicted, walks,
            walk_row, 1.0 if correction == "after_first" else None, priors)
        fitted[name] = declared_confidence(log_beliefs, evidence.labels[walk_row],
                                           row_model[walk_row], criterion=criterion)
    return fitted
