"""Held-out evidence and its leave-one-group-out folds: what every observe choice is scored on.

*Evidence* is the trained classifier's labels at X_rho on objects it did not train on: the
volume models. The k-th volume model of every class is *group* k; the groups are the units of
leave-one-group-out validation, which chooses RA-POMDP's model and fits the temperature without
the test models. A *fold* is one held-out group's rows and the models fitted without it
(:data:`Folds`; the models are fitted by
:func:`rapomdp.awareness.variants.leave_one_group_out`). The rest of the observe stage's
held-out machinery reads these: the RA variants' fits (:mod:`rapomdp.awareness.variants`), the
mixture (:mod:`rapomdp.awareness.mixture`), the wrong labels' shrinkage
(:mod:`rapomdp.awareness.shrinkage`), the belief's temperature
(:mod:`rapomdp.awareness.temperature`) and the choices in order
(:mod:`rapomdp.awareness.choices`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rapomdp.awareness.observation import ObservationModel
from rapomdp.awareness.quality import quality_from_probabilities

MIN_HELD_OUT_OBJECTS = 2
"""Held-out objects every class needs for a held-out choice to be made: with fewer, some class's
candidates would be compared on one object or none (docs/awareness.md §4.4)."""

Folds = list[tuple[np.ndarray, dict[str, ObservationModel]]]
"""Leave-one-group-out folds: each held-out group's rows (N,) bool and the models fitted
without it, by name."""


@dataclass
class Evidence:
    """Held-out outcomes of N objects at the V test viewpoints.

    Attributes:
        labels: (N,) int, each object's true class index.
        predicted: (N, V) int, the classifier's label of each object at each viewpoint.
        groups: (N,) int, each object's group: the k-th volume model of every class is group k
            (the units of leave-one-group-out validation).
    """

    labels: np.ndarray
    predicted: np.ndarray
    groups: np.ndarray

    def subset(self, mask: np.ndarray) -> Evidence:
        """The objects ``mask`` (N,) bool selects, as evidence of their own."""
        return Evidence(self.labels[mask], self.predicted[mask], self.groups[mask])

    @property
    def correct(self) -> np.ndarray:
        """(N, V) bool: whether the classifier was right on each object at each viewpoint."""
        return self.predicted == self.labels[:, None]


def recorded_evidence(observe: Mapping[str, np.ndarray]) -> Evidence:
    """The held-out evidence an observe stage's artefact records: what a refit reads.

    Args:
        observe: the arrays of ``observation_models.npz`` (``evidence_labels`` (N,),
            ``evidence_predictions`` (N, V), ``evidence_groups`` (N,)).

    Returns:
        The evidence the stage fitted its models on.
    """
    return Evidence(observe["evidence_labels"], observe["evidence_predictions"],
                    observe["evidence_groups"])


def recorded_scores(observe: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The viewpoint scores an observe stage's artefact records, keyed as the fits take them.

    Args:
        observe: the arrays of ``observation_models.npz``.

    Returns:
        ``mean`` and ``area``: the normalised Eq. 6 scores (C, V) in [0, 1]; ``similarity``: the
        seen-saliency similarity (C, V, V) ``ra_transfer`` reads, where the artefact has it.
    """
    scores = {"mean": observe["scores"], "area": observe["area_scores"]}
    if "view_similarity" in observe:
        scores["similarity"] = np.asarray(observe["view_similarity"], dtype=np.float64)
    return scores


def observed_probabilities(model: np.ndarray, labels: np.ndarray, predicted: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray]:
    """P(observed label) and P(correct) under a model for each outcome.

    Args:
        model: P(o | c, x) (V, C, C).
        labels: (N,) true class indices.
        predicted: (N, V) the labels observed at each viewpoint.

    Returns:
        Two (N, V) arrays: the probability of each observed label, and of the right one.
    """
    x = np.broadcast_to(np.arange(model.shape[0])[None], predicted.shape)
    t = np.broadcast_to(labels[:, None], predicted.shape)
    return model[x, t, predicted], model[x, t, t]


def validation_quality(evidence: Evidence, folds: Folds) -> list[dict[str, float | str]]:
    """Held-out quality of every model of the folds, each group scored by the models fitted
    without it, pooled over the groups.

    Args:
        evidence: the held-out evidence the folds split.
        folds: its leave-one-group-out folds; a model counts only if every fold has it.

    Returns:
        One row per model: ``model`` and the measures of :mod:`rapomdp.awareness.quality`
        (log-likelihood per label, Brier score, AUC, mean P(correct), accuracy). Empty without
        folds.
    """
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


def held_out_observed_probabilities(evidence: Evidence, folds: Folds, names: Sequence[str]
                                    ) -> np.ndarray:
    """The probability each of K models gives each held-out label, each object's by the model
    fitted without its group.

    Args:
        evidence: N held-out objects at V viewpoints.
        folds: its leave-one-group-out folds.
        names: the K models, each in every fold.

    Returns:
        (K, N, V) probabilities; NaN for the rows no fold holds out.
    """
    observed = np.full((len(names), *evidence.predicted.shape), np.nan)
    for held, models in folds:
        part = evidence.subset(held)
        for k, name in enumerate(names):
            observed[k, held] = observed_probabilities(models[name].probabilities, part.labels,
                                                       part.predicted)[0]
    return observed


def held_out_object_log_likelihoods(evidence: Evidence, folds: Folds) -> dict[str, np.ndarray]:
    """Every model's mean log-likelihood of each held-out object's labels, the object scored by
    the models fitted without its group: the unit the held-out choices compare over (one
    object's views are not independent; the objects are).

    Args:
        evidence: N held-out objects.
        folds: its leave-one-group-out folds.

    Returns:
        Per model present in every fold, (N,) mean log P(observed label) over the object's
        views (nats); NaN for the rows no fold holds out.
    """
    names = [n for n in (folds[0][1] if folds else {}) if all(n in m for _, m in folds)]
    observed = held_out_observed_probabilities(evidence, folds, names)
    return {name: np.log(np.maximum(observed[k], 1e-300)).mean(axis=1)
            for k, name in enumerate(names)}


def covered_rows(evidence: Evidence, folds: Folds) -> np.ndarray:
    """(N,) bool: the objects some fold holds out (those the held-out choices score)."""
    covered = np.zeros(len(evidence.labels), dtype=bool)
    for held, _ in folds:
        covered |= held
    return covered
