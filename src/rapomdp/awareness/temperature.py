"""The belief's corrections fitted on held-out walks: the likelihood temperature, the declared
confidence, and the passive classifier's softmax temperature.

Views of one object are correlated, so naive Bayes over them is overconfident. Every model's
likelihoods are raised to a temperature t fitted on random walks over the held-out groups'
outcomes (each group's beliefs updated by the models fitted without it), so that correlated
views count less than independent ones (docs/decisions/0003-belief-correction.md).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.optimize import minimize_scalar

from rapomdp.awareness.evidence import Evidence, Folds
from rapomdp.recognition.belief import (
    DECLARED_CRITERION,
    DECLARED_WALK_LENGTH,
    DeclaredConfidence,
    declared_confidence,
    fit_temperature,
    fold_of_rows,
    held_out_walks,
    walk_calibration,
    walk_log_beliefs,
)


def fit_softmax_temperature(probabilities: np.ndarray, labels: np.ndarray,
                            bounds: tuple[float, float] = (0.05, 20.0)) -> float:
    """The temperature scaling of the classifier's output that best predicts the true classes:
    the passive belief's calibration.

    Args:
        probabilities: held-out outputs (N, V, C) or (N, C).
        labels: (N,) the true classes.
        bounds: the interval T is searched in.

    Returns:
        T of p ** (1 / T) (renormalised) of greatest likelihood (T > 1: the output was
        overconfident).
    """
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


def _common_models(folds: Folds) -> list[str]:
    """The models every fold has, in the first fold's order."""
    return [n for n in folds[0][1] if all(n in m for _, m in folds)]


def held_out_temperatures(evidence: Evidence, folds: Folds, directions: np.ndarray,
                          length: int, starts_per_row: int, neighbours: int,
                          rng: np.random.Generator, after_first: bool = False
                          ) -> tuple[dict[str, float], dict[str, dict[str, float]]]:
    """One likelihood temperature per model, fitted on random walks over the held-out groups'
    outcomes, each group's beliefs updated by the models fitted without it.

    Args:
        evidence: the held-out outcomes.
        folds: its leave-one-group-out folds.
        directions: (V, 3) unit viewpoint directions (the walks move to near ones).
        length: views per walk.
        starts_per_row: walks per held-out object.
        neighbours: a walk moves to one of this many nearest unvisited viewpoints.
        rng: the walks' random stream.
        after_first: fit a temperature for the views after the first, the first counting in
            full: recorded beside the belief's own fit for comparison (``after_first_*`` in
            ``calibration.json: held_out_belief``), never applied.

    Returns:
        Per model, its temperature, and the calibration of the held-out beliefs
        (:func:`~rapomdp.recognition.belief.walk_calibration`: max belief against a right
        argmax after the first and the last step, naive (t = 1) and tempered, and each one's
        log loss). Empty without folds.
    """
    if not folds:
        return {}, {}
    row_model = fold_of_rows([held for held, _ in folds], len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, directions, rng, length, starts_per_row,
                                     neighbours)
    temperatures, calibration = {}, {}
    for name in _common_models(folds):
        models = [m[name].probabilities for _, m in folds]
        first = 1.0 if after_first else None
        t = fit_temperature(models, row_model, evidence.labels, evidence.predicted, walks,
                            walk_row, first_temperature=first)
        temperatures[name] = t
        calibration[name] = walk_calibration(t, models, row_model, evidence.labels,
                                             evidence.predicted, walks, walk_row, first)
    return temperatures, calibration


def held_out_declared_confidence(evidence: Evidence, folds: Folds,
                                 temperatures: Mapping[str, float], directions: np.ndarray,
                                 starts_per_row: int, neighbours: int,
                                 rng: np.random.Generator,
                                 criterion: str = DECLARED_CRITERION
                                 ) -> dict[str, DeclaredConfidence]:
    """Per model, the declared confidence fitted where held-out walks stop.

    Args:
        evidence: the held-out outcomes.
        folds: its leave-one-group-out folds.
        temperatures: each model's likelihood temperature (1 where absent).
        directions: (V, 3) unit viewpoint directions.
        starts_per_row: walks per held-out object, each of
            :data:`~rapomdp.recognition.belief.DECLARED_WALK_LENGTH` views.
        neighbours: a walk moves to one of this many nearest unvisited viewpoints.
        rng: the walks' random stream.
        criterion: what the declared temperature a minimises
            (:data:`~rapomdp.recognition.belief.DECLARED_CRITERIA`).

    Returns:
        :func:`~rapomdp.recognition.belief.declared_confidence` per model, each group's walks
        updated by the tempered models fitted without it. Empty without folds.
    """
    if not folds:
        return {}
    row_model = fold_of_rows([held for held, _ in folds], len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, directions, rng, DECLARED_WALK_LENGTH,
                                     starts_per_row, neighbours)
    fitted: dict[str, DeclaredConfidence] = {}
    for name in _common_models(folds):
        models = [m[name].probabilities for _, m in folds]
        log_beliefs = walk_log_beliefs(temperatures.get(name, 1.0), models, row_model,
                                       evidence.predicted, walks, walk_row)
        fitted[name] = declared_confidence(log_beliefs, evidence.labels[walk_row],
                                           row_model[walk_row], criterion=criterion)
    return fitted
