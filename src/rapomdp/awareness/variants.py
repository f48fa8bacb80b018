"""The observation models fitted on held-out evidence: every RA variant, the Classifier's and the
black box's, and the leave-one-group-out folds of them.

An RA variant maps a viewpoint score to P(correct | c, x) (a calibration fitted on the held-out
labels) and spreads the rest of the row over the class's wrong labels as counted held out. The
variants differ in the score they read and in what else enters P(correct) (:data:`RA_VARIANTS`).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np

from rapomdp.awareness.evidence import Evidence, Folds
from rapomdp.awareness.observation import (
    BlackBoxObservationModel,
    ClassifierObservationModel,
    ObservationModel,
    RAObservationModel,
    TransferObservationModel,
    calibrate_correctness,
    calibrate_per_class,
    ridge_logistic,
    wrong_label_distribution,
)
from rapomdp.awareness.transfer import (
    DEFAULT_TRANSFER_KERNEL,
    VIEWPOINT_BANDWIDTH_DEG,
    TransferKernel,
    angle_deg,
    transfer_confusion,
)
from rapomdp.config import ObserveConfig
from rapomdp.recognition.belief import held_out_groups

RA_VARIANTS = {
    "paper": ("mean", False),  # Eq. 6 mean saliency seen, one calibration for every class
    "class": ("mean", True),  # + one intercept per class (its difficulty), shared slope
    "area": ("area", False),  # the salient area seen (Eq. 6's sum), one calibration
    "class_area": ("area", True),  # the salient area seen + per-class intercepts
    "viewpoint": ("area", True),  # + the held-out per-viewpoint evidence, stacked
    "region": ("area", True),  # + the held-out accuracy per viewpoint pooled over classes
    "transfer": ("similarity", False),  # whole rows shared by views that see the same saliency
}
"""RA variant -> (viewpoint score it calibrates, per-class intercepts?)."""
STACKED_VARIANTS = ("viewpoint", "region")
"""The RA variants whose per-viewpoint term is stacked over groups of held-out evidence (they
need two groups or more)."""
REPORTED_ONLY = frozenset({"region"})
"""RA variants fitted and reported in the validation table but never used: ``region`` is not
selectable (docs/decisions/0006-ra-model-mixture.md) and the mixture leaves it out."""
VIEWPOINT_PRIOR = 2.0
"""Pseudo-observations of the class's accuracy added to each viewpoint's kernel count."""
VIEWPOINT_METHOD = "logistic_score_and_viewpoint_evidence"
"""calibration.json ``method`` of ``ra_viewpoint``'s fit."""
REGION_METHOD = "logistic_score_and_region_evidence"
"""calibration.json ``method`` of ``ra_region``'s fit."""


def viewpoint_logit(labels: np.ndarray, predicted: np.ndarray, classes: int,
                    directions: np.ndarray, pooled: bool = False) -> np.ndarray:
    """The classifier's held-out accuracy at each (class, viewpoint) on the logit scale, centred.

    Kernel-smoothed over neighbouring viewpoints (Gaussian in the angle,
    :data:`~rapomdp.awareness.transfer.VIEWPOINT_BANDWIDTH_DEG`), shrunk to the class's accuracy
    by :data:`VIEWPOINT_PRIOR` pseudo-observations, and centred over the viewpoints: it says
    which views are harder, the class intercepts of the models that read it say how hard.
    (Uncentred, its level would be the other groups' accuracy, which in leave-one-group-out
    stacking falls as the held-out group's rises: the fit read that as a falling weight,
    docs/awareness.md §4.2.)

    Args:
        labels: (N,) true classes of the outcomes.
        predicted: (N, V) the classifier's labels.
        classes: C.
        directions: (V, 3) unit viewpoint directions.
        pooled: the accuracy at each viewpoint over every class together (the same row for
            each class), as ``ra_region`` reads it.

    Returns:
        (C, V) centred logits.
    """
    kernel = np.exp(-0.5 * (angle_deg(directions) / VIEWPOINT_BANDWIDTH_DEG) ** 2)  # (V, V)
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
    """``ra_viewpoint``'s P(correct): the saliency score and the held-out per-viewpoint
    evidence together.

    The weights are fitted by stacking — each group's rows see the viewpoint logit computed
    from the *other* groups only — so the evidence is never scored on itself; the final logit
    uses every group. Both weights are kept non-negative (a falling feature is dropped).

    Args:
        evidence: the held-out outcomes.
        score: (C, V) the normalised viewpoint score it reads.
        classes: C.
        directions: (V, 3) unit viewpoint directions.
        pooled: ``ra_region``: the accuracy per viewpoint pooled over every class.

    Returns:
        The fitted P(correct), or None with a single group (nothing to stack on).
    """
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


def fit_observation_models(evidence: Evidence, scores: dict[str, np.ndarray],
                           classes: Sequence[str], cfg: ObserveConfig,
                           directions: np.ndarray | None = None,
                           transfer_kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL,
                           names: Collection[str] | None = None
                           ) -> dict[str, ObservationModel]:
    """Every RA variant (``ra_<variant>``), the Classifier and the black-box model, fitted on
    held-out evidence.

    Args:
        evidence: the held-out outcomes.
        scores: the per-class normalised viewpoint scores (C, V) by kind (``mean``, ``area``)
            and, under ``similarity``, the (C, V, V) seen-saliency similarity of the viewpoints
            (:func:`~rapomdp.awareness.transfer.salient_view_similarity`).
        classes: the C class names, in order.
        cfg: the observe section (calibration form and pseudo-counts).
        directions: (V, 3) unit viewpoint directions; ``ra_viewpoint``, ``ra_region`` (which
            also need two groups of evidence) and ``ra_transfer`` need them.
        transfer_kernel: ``ra_transfer``'s kernel.
        names: fit only these models (all when None).

    Returns:
        Each model P(o | c, x) (V, C, C) by name, in :data:`RA_VARIANTS`' order then
        ``classifier`` and ``blackbox``.
    """
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


def leave_one_group_out(evidence: Evidence, scores: dict[str, np.ndarray],
                        classes: Sequence[str], cfg: ObserveConfig,
                        directions: np.ndarray | None = None,
                        transfer_kernel: TransferKernel = DEFAULT_TRANSFER_KERNEL) -> Folds:
    """The leave-one-group-out folds of :func:`fit_observation_models`.

    Args:
        evidence, scores, classes, cfg, directions, transfer_kernel: as
            :func:`fit_observation_models` takes them.

    Returns:
        For every group whose complement still covers every class: (its rows (N,) bool, the
        models fitted on the other groups). Empty when there is one group only.
    """
    return [(held, fit_observation_models(evidence.subset(~held), scores, classes, cfg,
                                          directions, transfer_kernel))
            for held in held_out_groups(evidence.labels, evidence.groups)]
