"""Observation models P(o | class, viewpoint) for the planner.

The observation o is the classifier's predicted label. Every model is an array
``probabilities`` of shape (V, C, C) = [viewpoint x, true class c, observed label o], each row
summing to 1; V follows the test viewpoints X_rho in order and C the dataset's classes in order.

* :class:`RAObservationModel` (recognition-aware, the paper's): the probability of the correct
  label is a monotone function of the viewpoint's saliency score (Eq. 6), calibrated on renders
  of the volume models; the rest of the row follows the classifier's confusion.
* :class:`ClassifierObservationModel` (the paper's "Classifier" ablation, the box closed): the
  empirical per-viewpoint confusion of the classifier on the volume models at X_rho, plus a
  pseudo-count.
* :class:`BlackBoxObservationModel`: one confusion for every viewpoint (no viewpoint knowledge).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import isotonic_regression
from sklearn.exceptions import ConvergenceWarning
from sklearn.linear_model import LogisticRegression

from rapomdp.io import load_npz
from rapomdp.recognition.evaluation import viewpoint_confusion

PROBABILITY_FLOOR = 1e-3
"""RA's correct-label probability is kept in [floor, 1 - floor]: no observation is impossible."""


class ObservationModel:
    """P(o | class, viewpoint) as ``probabilities`` (V, C, C); rows sum to 1.

    Args:
        probabilities: (V, C, C), P(o | c, x) at index [x, c, o].
        classes: the C class names, in order.

    Raises:
        ValueError: not (V, C, C) for the classes given, or not rows of probabilities.
    """

    name = "observation"

    def __init__(self, probabilities: np.ndarray, classes: Sequence[str]) -> None:
        p = np.asarray(probabilities, dtype=np.float64)
        c = len(classes)
        if p.ndim != 3 or p.shape[1:] != (c, c):
            raise ValueError(f"observation probabilities must be (V, {c}, {c}) for {c} classes, "
                             f"got shape {p.shape}")
        if np.any(p < 0) or not np.allclose(p.sum(axis=2), 1.0, atol=1e-6):
            raise ValueError("observation probabilities must be non-negative rows summing to 1")
        self.probabilities = p
        self.classes = list(classes)

    @property
    def viewpoints(self) -> int:
        return self.probabilities.shape[0]

    def likelihood(self, viewpoint: int, observation: int) -> np.ndarray:
        """P(o | c, x) for every class c (C,): the factor of a Bayes belief update."""
        return self.probabilities[viewpoint, :, observation]

    def correct_probability(self) -> np.ndarray:
        """P(o = c | c, x) as (V, C)."""
        return np.diagonal(self.probabilities, axis1=1, axis2=2)


@dataclass
class ScoreCalibration:
    """A monotone non-decreasing map from a viewpoint score in [0, 1] to P(correct).

    ``logistic``: ``sigmoid(a + b * s)`` with ``b >= 0``, fitted by maximum likelihood
    (:func:`ridge_logistic`) with a tiny ridge against separation. ``isotonic``:
    pool-adjacent-violators on the scores, interpolated linearly between the pooled blocks'
    mean scores.
    """

    method: str
    intercept: float = 0.0
    slope: float = 0.0
    knots_x: np.ndarray = field(default_factory=lambda: np.zeros(0))
    knots_y: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __call__(self, scores: np.ndarray) -> np.ndarray:
        s = np.asarray(scores, dtype=np.float64)
        if self.method == "logistic":
            p = 1.0 / (1.0 + np.exp(-(self.intercept + self.slope * s)))
        else:
            p = np.interp(s, self.knots_x, self.knots_y)
        return np.clip(p, PROBABILITY_FLOOR, 1.0 - PROBABILITY_FLOOR)

    def to_dict(self) -> dict[str, object]:
        return {"method": self.method, "intercept": self.intercept, "slope": self.slope,
                "knots_x": self.knots_x.tolist(), "knots_y": self.knots_y.tolist()}


def ridge_logistic(x: np.ndarray, y: np.ndarray, ridge: float) -> np.ndarray:
    """Weights ``w`` minimising the log-loss of sigmoid(x @ w) plus ``ridge / 2 * |w|^2``:
    scikit-learn's ``LogisticRegression`` (Newton-Cholesky, ``C = 1 / ridge``, the intercept a
    column of ``x``). Two all-zero rows, one of each label, let it fit outcomes of one kind
    (their gradient is zero: the weights are unchanged)."""
    x = np.concatenate([np.asarray(x, dtype=np.float64), np.zeros((2, x.shape[1]))])
    y = np.concatenate([np.asarray(y, dtype=np.float64), [0.0, 1.0]])
    model = LogisticRegression(C=1.0 / ridge, fit_intercept=False, solver="newton-cholesky",
                               tol=1e-10, max_iter=100)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        model.fit(x, y > 0.5)
    return np.asarray(model.coef_[0], dtype=np.float64)


def _fit_logistic(s: np.ndarray, y: np.ndarray, ridge: float = 1e-3) -> tuple[float, float]:
    """Maximum-likelihood (a, b) of sigmoid(a + b s) with b >= 0."""
    w = ridge_logistic(np.stack([np.ones_like(s), s], axis=1), y, ridge)
    if w[1] < 0:  # monotone: the best non-increasing fit is a constant
        mean = float(np.clip(y.mean(), 1e-6, 1 - 1e-6))
        return float(np.log(mean / (1 - mean))), 0.0
    return float(w[0]), float(w[1])


@dataclass
class ClassScoreCalibration:
    """P(correct | class c, score s) = sigmoid(a_c + b * s): one intercept per class (its
    difficulty), one shared slope ``b >= 0`` (what the saliency score adds). Applied to scores
    (C, V), rows in class order."""

    intercepts: np.ndarray
    slope: float
    method: str = "logistic_per_class"

    def __call__(self, scores: np.ndarray) -> np.ndarray:
        s = np.asarray(scores, dtype=np.float64)
        p = 1.0 / (1.0 + np.exp(-(self.intercepts[:, None] + self.slope * s)))
        return np.clip(p, PROBABILITY_FLOOR, 1.0 - PROBABILITY_FLOOR)

    def to_dict(self) -> dict[str, object]:
        return {"method": self.method, "intercepts": self.intercepts.tolist(),
                "slope": self.slope}


def calibrate_per_class(scores: np.ndarray, correct: np.ndarray, classes: np.ndarray,
                        count: int, ridge: float = 1e-2) -> ClassScoreCalibration:
    """Fit :class:`ClassScoreCalibration` on pairs (score, right?, class) by Newton steps with a
    small ridge (a class that is always right or always wrong keeps a finite intercept)."""
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y = np.asarray(correct, dtype=np.float64).reshape(-1)
    g = np.asarray(classes).reshape(-1)
    x = np.zeros((s.size, count + 1))
    x[np.arange(s.size), g] = 1.0
    x[:, count] = s
    w = ridge_logistic(x, y, ridge)
    if w[count] < 0:  # monotone in the score: refit the intercepts alone
        rate = np.clip((np.bincount(g, weights=y, minlength=count) + 0.5)
                       / (np.bincount(g, minlength=count) + 1.0), 1e-6, 1 - 1e-6)
        return ClassScoreCalibration(np.log(rate / (1 - rate)), 0.0)
    return ClassScoreCalibration(w[:count].copy(), float(w[count]))


def calibrate_correctness(scores: np.ndarray, correct: np.ndarray,
                          method: str = "logistic") -> ScoreCalibration:
    """Fit P(correct | score) on (score, classifier right?) pairs; monotone by construction."""
    s = np.asarray(scores, dtype=np.float64).reshape(-1)
    y = np.asarray(correct, dtype=np.float64).reshape(-1)
    if s.size != y.size or s.size == 0:
        raise ValueError(f"calibration needs as many scores as outcomes, got {s.size}, {y.size}")
    if method == "logistic":
        a, b = _fit_logistic(s, y)
        return ScoreCalibration("logistic", intercept=a, slope=b)
    if method == "isotonic":
        order = np.argsort(s, kind="stable")
        # tie groups first, so equal scores share one value
        keys, start = np.unique(s[order], return_index=True)
        sums = np.add.reduceat(y[order], start)
        counts = np.diff(np.r_[start, s.size]).astype(np.float64)
        fit = isotonic_regression(sums / counts, weights=counts, increasing=True)
        begins, ends = fit.blocks[:-1], fit.blocks[1:]
        means = fit.x[begins]
        block_x = np.array([np.average(keys[b:e], weights=counts[b:e])
                            for b, e in zip(begins, ends, strict=True)])
        return ScoreCalibration("isotonic", knots_x=block_x, knots_y=means)
    raise ValueError(f"unknown calibration {method!r}; choose 'logistic' or 'isotonic'")


def wrong_label_distribution(true_labels: np.ndarray, predicted: np.ndarray, classes: int,
                             pseudo_count: float) -> np.ndarray:
    """Where the classifier's mistakes go: (C, C), row c = P(o | c, o != c), diagonal 0.

    Counted over every (model, viewpoint) pair given, plus ``pseudo_count`` on every wrong label.
    """
    counts = np.zeros((classes, classes))
    np.add.at(counts, (np.asarray(true_labels).reshape(-1), np.asarray(predicted).reshape(-1)), 1)
    counts += pseudo_count
    np.fill_diagonal(counts, 0.0)
    totals = counts.sum(axis=1, keepdims=True)
    uniform = (1.0 - np.eye(classes)) / max(classes - 1, 1)
    return np.where(totals > 0, counts / np.where(totals > 0, totals, 1.0), uniform)


class RAObservationModel(ObservationModel):
    """Recognition-aware: P(o = c | c, x) = calibration(score[c, x]); the remaining mass
    ``1 - P`` spread over the wrong labels as the classifier's confusion spreads it."""

    name = "ra"

    def __init__(self, scores: np.ndarray,
                 calibration: ScoreCalibration | ClassScoreCalibration,
                 wrong_labels: np.ndarray, classes: Sequence[str]) -> None:
        scores = np.asarray(scores, dtype=np.float64)  # (C, V), normalised per class
        c = len(classes)
        if scores.ndim != 2 or scores.shape[0] != c:
            raise ValueError(f"scores must be (C={c}, V), got shape {scores.shape}")
        correct = calibration(scores).T  # (V, C)
        p = (1.0 - correct)[:, :, None] * np.asarray(wrong_labels)[None]
        idx = np.arange(c)
        p[:, idx, idx] = correct
        super().__init__(p, classes)
        self.scores, self.calibration = scores, calibration


@dataclass
class TransferCalibration:
    """What ``ra_transfer`` was fitted with (it has no score calibration: its rows are the
    held-out labels shared between views that see alike saliency)."""

    method: str = "salient_view_transfer"

    def to_dict(self) -> dict[str, object]:
        return {"method": self.method}


class TransferObservationModel(ObservationModel):
    """Recognition-aware by transfer: each viewpoint's whole row P(o | c, x) pooled from the
    held-out labels at the viewpoints whose seen saliency resembles x's
    (:func:`rapomdp.awareness.transfer.transfer_confusion`)."""

    name = "ra_transfer"

    def __init__(self, probabilities: np.ndarray, classes: Sequence[str]) -> None:
        super().__init__(probabilities, classes)
        self.calibration = TransferCalibration()


@dataclass
class MixtureCalibration:
    """What ``ra_mixture`` was fitted with: each RA variant's weight (they sum to 1), chosen by
    the held-out likelihood of the held-out labels (it has no score calibration of its own)."""

    weights: dict[str, float]
    method: str = "held_out_mixture"

    def to_dict(self) -> dict[str, object]:
        return {"method": self.method, "weights": dict(self.weights)}


class MixtureObservationModel(ObservationModel):
    """Recognition-aware by averaging: P(o | c, x) = Σ_v w_v P_v(o | c, x) over RA variants,
    the weights w (a simplex) those that best predict held-out labels
    (:func:`rapomdp.awareness.mixture.ra_mixture_folds`). One variant picked from a few
    held-out objects is brittle; a weighted average of them is not."""

    name = "ra_mixture"

    def __init__(self, models: Mapping[str, ObservationModel], weights: Mapping[str, float],
                 classes: Sequence[str]) -> None:
        if set(weights) - set(models):
            raise ValueError(f"weights for models not given: {sorted(set(weights) - set(models))}")
        w = np.array([weights[name] for name in weights], dtype=np.float64)
        if w.size == 0 or np.any(w < 0) or not np.isclose(w.sum(), 1.0):
            raise ValueError(f"mixture weights must be a distribution, got {dict(weights)}")
        table = np.einsum("k,kvco->vco", w, np.stack([models[n].probabilities for n in weights]))
        super().__init__(table, classes)
        self.calibration = MixtureCalibration({name: float(x) for name, x in weights.items()})


class ClassifierObservationModel(ObservationModel):
    """The classifier's empirical per-viewpoint confusion (the box closed), with pseudo-counts:
    P(o | c, x) = (n(c, x, o) + a) / (n(c, x) + C a)."""

    name = "classifier"

    def __init__(self, true_labels: np.ndarray, predicted: np.ndarray, classes: Sequence[str],
                 pseudo_count: float) -> None:
        super().__init__(viewpoint_confusion(true_labels, predicted, len(classes), pseudo_count),
                         classes)


class BlackBoxObservationModel(ObservationModel):
    """One confusion matrix for every viewpoint, with pseudo-counts (no viewpoint knowledge)."""

    name = "blackbox"

    def __init__(self, true_labels: np.ndarray, predicted: np.ndarray, classes: Sequence[str],
                 pseudo_count: float) -> None:
        predicted = np.asarray(predicted)
        c = len(classes)
        counts = np.full((c, c), float(pseudo_count))
        t = np.broadcast_to(np.asarray(true_labels)[:, None], predicted.shape)
        np.add.at(counts, (t, predicted), 1.0)
        table = counts / counts.sum(axis=1, keepdims=True)
        super().__init__(np.broadcast_to(table, (predicted.shape[1], c, c)).copy(), classes)


def load_observation_models(path: str | Path) -> dict[str, ObservationModel]:
    """The observe stage's ``observation_models.npz``: every (V, C, C) model by name."""
    data = load_npz(path)
    classes = [str(c) for c in data["classes"]]
    names = [str(n) for n in data["models"]]
    return {name: ObservationModel(data[name], classes) for name in names}
