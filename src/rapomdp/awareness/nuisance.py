"""A per-object nuisance: the belief over (class, instance type) that keeps views of one object
dependent (``observe.belief: nuisance``).

The classifier's errors are correlated *within an object*: an unusual mug is a cup from most
sides. Naive Bayes treats every view as independent given the class and counts that one piece
of evidence many times. Here each object has a hidden *instance type* τ, constant over its
views: *typical* (τ = 0), whose labels follow the base observation model P(o | c, x) fitted on
the typical held-out objects, or *atypical* (τ = 1), whose labels follow one viewpoint-free row
A(o | c) per class — the confusion the atypical held-out objects of that class showed, shrunk to
the pooled atypical confusion (:data:`ATYPICAL_PSEUDO_OBJECTS` objects' worth). Views are
independent given (c, τ), not given c; the belief is over the 2C pairs and a declaration reads
its class marginal. The planner solves the same model (:mod:`rapomdp.planning.momdp`: hidden
state τ·C + c), from the same prior (1 − π, π)/C.

Fitted by EM over held-out objects (each an evidence row: a class and its labels at every
viewpoint of X_rho): the E-step's probability that object r is atypical compares its labels'
likelihood under the typical model *fitted without r's group* (out of sample, so an object does
not explain itself) with that under the atypical rows counted without r; the M-step updates π
and the rows. The typical model is then refitted on the objects more likely typical (a class
none of whose objects is keeps the model fitted on all of them).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rapomdp.awareness.evidence import Evidence
from rapomdp.awareness.observation import wrong_label_distribution
from rapomdp.recognition.belief import held_out_groups

NUISANCE_TYPES = 2
"""Instance types of the hidden state: typical, atypical."""
ATYPICAL_PSEUDO_OBJECTS = 1.0
"""Objects' worth of the pooled atypical confusion each class's atypical row is shrunk to."""
WEIGHT_BOUNDS = (1e-12, 0.5)
"""π is kept in these bounds: at most half the objects atypical (the typical type is the one
the base model describes); on evidence where no object is atypical π falls to the floor and
the belief is naive Bayes's (to ~1e-12)."""
EM_ITERATIONS = 100
EM_TOLERANCE = 1e-8

#: fits the base models on evidence: (evidence, names or None) -> {name: (V, C, C)}
BaseFit = Callable[[Evidence, Sequence[str] | None], dict[str, np.ndarray]]


@dataclass
class NuisanceModel:
    """A model's two instance types: the ``typical`` rows (V, C, C), the ``atypical`` rows
    (V, C, C) (the same for every viewpoint), the prior probability ``weight`` π of an atypical
    object, and the fit's ``responsibilities`` (N,) P(atypical | object) on its evidence."""

    typical: np.ndarray
    atypical: np.ndarray
    weight: float
    responsibilities: np.ndarray
    iterations: int = 0

    @property
    def probabilities(self) -> np.ndarray:
        """P(o | (τ, c), x) (V, 2C, C), hidden state τ·C + c: the planner's and the belief's."""
        return np.concatenate([self.typical, self.atypical], axis=1)

    @property
    def prior(self) -> np.ndarray:
        """The start belief (2C,) over (τ, c): uniform over classes, (1 − π, π) over types."""
        c = self.typical.shape[1]
        return np.concatenate([np.full(c, (1.0 - self.weight) / c), np.full(c, self.weight / c)])

    @property
    def single_view(self) -> np.ndarray:
        """The one-view model (V, C, C) it implies: (1 − π) typical + π atypical."""
        return (1.0 - self.weight) * self.typical + self.weight * self.atypical

    def to_dict(self) -> dict[str, float | int]:
        idx = np.arange(self.typical.shape[1])
        return {"weight": self.weight, "iterations": self.iterations,
                "atypical_objects": float(self.responsibilities.sum()),
                "objects": int(self.responsibilities.size),
                "atypical_accuracy": float(self.atypical[0, idx, idx].mean()),
                "typical_accuracy": float(self.typical[:, idx, idx].mean())}


def typed_probabilities(typical: np.ndarray, atypical: np.ndarray) -> np.ndarray:
    """The typed model (V, 2C, C) of two (V, C, C) models, hidden state τ·C + c."""
    return np.concatenate([typical, atypical], axis=1)


def object_log_likelihoods(model: np.ndarray, labels: np.ndarray,
                           predicted: np.ndarray) -> np.ndarray:
    """Σ_x log P(label at x | c_r, x) (N,) of each object's labels ``predicted`` (N, V) under
    ``model`` (V, C, C), its class ``labels`` (N,)."""
    x = np.broadcast_to(np.arange(model.shape[0])[None], predicted.shape)
    c = np.broadcast_to(np.asarray(labels)[:, None], predicted.shape)
    return np.log(np.maximum(model[x, c, predicted], 1e-300)).sum(axis=1)


def out_of_sample_log_likelihoods(evidence: Evidence, fit: BaseFit,
                                  names: Sequence[str]) -> dict[str, np.ndarray]:
    """Each object's log-likelihood (N,) under each named base model fitted without the
    object's group (leave-one-group-out); rows of a group that cannot be held out (its
    complement misses a class, or there is one group only) and models that cannot be fitted
    without it (``ra_viewpoint`` stacks over two groups) are scored in sample."""
    out = {name: np.zeros(len(evidence.labels)) for name in names}
    covered = {name: np.zeros(len(evidence.labels), dtype=bool) for name in names}
    for held in held_out_groups(evidence.labels, evidence.groups):
        models = fit(evidence.subset(~held), names)
        for name in (n for n in names if n in models):  # some need more groups to fit
            out[name][held] = object_log_likelihoods(models[name], evidence.labels[held],
                                                     evidence.predicted[held])
            covered[name] |= held
    if not all(c.all() for c in covered.values()):
        models = fit(evidence, names)
        for name in names:
            rest = ~covered[name]
            out[name][rest] = object_log_likelihoods(models[name], evidence.labels[rest],
                                                     evidence.predicted[rest])
    return out


def _atypical_rows(counts: np.ndarray, labels: np.ndarray, weights: np.ndarray,
                   wrong: np.ndarray, views: int) -> np.ndarray:
    """Per-class atypical rows (C, C) from the objects' label counts (N, C) weighted by their
    P(atypical): each class's weighted counts plus :data:`ATYPICAL_PSEUDO_OBJECTS` objects of
    the pooled row (the weighted accuracy over every class on the diagonal, the class's wrong
    labels ``wrong`` (C, C) for the rest)."""
    c = wrong.shape[0]
    right = counts[np.arange(len(labels)), labels]
    accuracy = (float(weights @ right) + 0.5) / (float(weights.sum()) * views + 1.0)
    pooled = (1.0 - accuracy) * wrong + accuracy * np.eye(c)
    onehot = np.eye(c)[labels]  # (N, C)
    weighted = (onehot * weights[:, None]).T @ counts  # (C, C)
    objects = onehot.T @ weights  # (C,)
    rows = weighted + ATYPICAL_PSEUDO_OBJECTS * views * pooled
    return rows / (objects[:, None] * views + ATYPICAL_PSEUDO_OBJECTS * views)


def fit_nuisance(evidence: Evidence, typical_log_likelihood: np.ndarray, classes: int,
                 pseudo_count: float) -> tuple[float, np.ndarray, np.ndarray, int]:
    """EM over the held-out objects for π and the atypical rows, the typical model's
    log-likelihood of each object (N,) held fixed (out of sample:
    :func:`out_of_sample_log_likelihoods`). Returns π, the atypical rows (C, C) of the
    ``classes``, each object's P(atypical) (N,) and the iterations. The E-step scores an object
    under its class's atypical row counted without it (closed form: its own counts removed).
    ``pseudo_count``: per (class, wrong label) of the pooled wrong-label distribution."""
    labels, predicted = evidence.labels, evidence.predicted
    n, views = predicted.shape
    c = classes
    rows = np.broadcast_to(labels[:, None], predicted.shape)
    wrong = wrong_label_distribution(rows, predicted, c, pseudo_count)
    counts = np.zeros((n, c))
    np.add.at(counts, (np.repeat(np.arange(n), views), predicted.ravel()), 1.0)
    onehot = np.eye(c)[labels]
    # start: the objects less often right than their class's others are the atypical ones
    right = counts[np.arange(n), labels] / views
    class_mean = (onehot.T @ right) / np.maximum(onehot.sum(axis=0), 1)
    gamma = (right < 0.5 * class_mean[labels]).astype(np.float64)
    weight = float(np.clip(gamma.mean(), *WEIGHT_BOUNDS))
    previous = -np.inf
    iterations = 0
    while iterations < EM_ITERATIONS:
        iterations += 1
        table = _atypical_rows(counts, labels, gamma, wrong, views)  # (C, C)
        # leave-one-object-out atypical rows for the E-step: remove each object's counts
        own = gamma[:, None] * counts  # (N, C)
        class_counts = table[labels] * (onehot @ (onehot.T @ gamma) + ATYPICAL_PSEUDO_OBJECTS
                                        )[:, None] * views
        loo = (class_counts - own) / ((onehot @ (onehot.T @ gamma) - gamma
                                       + ATYPICAL_PSEUDO_OBJECTS)[:, None] * views)
        atypical_ll = (counts * np.log(np.maximum(loo, 1e-300))).sum(axis=1)
        z = np.log(weight / (1.0 - weight)) + atypical_ll - typical_log_likelihood
        gamma = 1.0 / (1.0 + np.exp(-np.clip(z, -700, 700)))
        weight = float(np.clip(gamma.mean(), *WEIGHT_BOUNDS))
        joint = float(np.sum(np.logaddexp(np.log(1.0 - weight) + typical_log_likelihood,
                                          np.log(weight) + atypical_ll)))
        if joint - previous < EM_TOLERANCE * max(1.0, abs(joint)):
            break
        previous = joint
    return weight, _atypical_rows(counts, labels, gamma, wrong, views), gamma, iterations


def fit_nuisance_models(evidence: Evidence, fit: BaseFit, names: Sequence[str],
                        pseudo_count: float) -> dict[str, NuisanceModel]:
    """The nuisance model of every named base model on ``evidence``: EM for π and the atypical
    rows (:func:`fit_nuisance`), then the typical rows refitted on the objects more likely
    typical (P(atypical) < 1/2; a class with none keeps the rows fitted on all its objects)."""
    names = list(names)
    typical_ll = out_of_sample_log_likelihoods(evidence, fit, names)
    full = fit(evidence, names)
    out = {}
    for name in names:
        c = full[name].shape[1]
        weight, table, gamma, iterations = fit_nuisance(evidence, typical_ll[name], c,
                                                        pseudo_count)
        typical_rows = gamma < 0.5
        kept = np.bincount(evidence.labels[typical_rows], minlength=c) > 0
        typical = full[name].copy()
        if typical_rows.any() and not typical_rows.all():
            refit = fit(evidence.subset(typical_rows), [name])[name]
            typical[:, kept] = refit[:, kept]
        atypical = np.broadcast_to(table, typical.shape).copy()
        out[name] = NuisanceModel(typical, atypical, weight, gamma, iterations)
    return out


def nuisance_belief_models(evidence: Evidence, held: Sequence[np.ndarray], fit: BaseFit,
                           names: Sequence[str], pseudo_count: float
                           ) -> tuple[dict[str, NuisanceModel], list[dict[str, NuisanceModel]]]:
    """The nuisance models of the named base models fitted on all of ``evidence`` (the
    planner's and the closed loop's) and, for every held-out mask of ``held`` (the folds of
    leave-one-group-out), on the rest (what the held-out walks and closed loop score)."""
    return (fit_nuisance_models(evidence, fit, names, pseudo_count),
            [fit_nuisance_models(evidence.subset(~mask), fit, names, pseudo_count)
             for mask in held])
