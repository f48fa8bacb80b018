"""Single-view evaluation of the classifier on the *test* models.

Two view sets: the test viewpoints X_rho (near-uniform on the upper hemisphere, rendered here)
and the whole training viewsphere (the render stage's images of the test models). For each:
accuracy overall and per class, the confusion matrix, and for X_rho the accuracy and mean
true-class probability per viewpoint (over the test models).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.io import atomic_path


def viewpoint_label_counts(true_labels: np.ndarray, predicted: np.ndarray,
                           classes: int) -> np.ndarray:
    """How often each label was output per viewpoint and true class: n(x, c, o) (V, C, C),
    from labels (M,) and predictions (M, V)."""
    true_labels = np.asarray(true_labels)  # (M,)
    predicted = np.asarray(predicted)  # (M, V)
    views = predicted.shape[1]
    flat = (np.arange(views)[None] * classes + true_labels[:, None]) * classes + predicted
    return np.bincount(flat.ravel(), minlength=views * classes * classes).astype(
        np.float64).reshape(views, classes, classes)


def viewpoint_confusion(true_labels: np.ndarray, predicted: np.ndarray, classes: int,
                        pseudo_count: float) -> np.ndarray:
    """A classifier's empirical confusion per viewpoint, with pseudo-counts: (V, C, C) with
    P(o | c, x) = (n(c, x, o) + a) / (n(c, x) + C a), from labels (M,) and predictions (M, V).

    The "Classifier" observation model of the CNN and the VP-tree baseline's are both this.
    """
    if pseudo_count <= 0:
        raise ValueError(f"the pseudo-count must be positive, got {pseudo_count}")
    counts = viewpoint_label_counts(true_labels, predicted, classes) + pseudo_count
    return counts / counts.sum(axis=2, keepdims=True)


@dataclass
class SingleViewResult:
    """Probabilities (models, views, C) of test models with labels (models,)."""

    name: str
    classes: list[str]
    probabilities: np.ndarray
    labels: np.ndarray

    @property
    def predictions(self) -> np.ndarray:
        return self.probabilities.argmax(axis=2)

    @property
    def correct(self) -> np.ndarray:
        """(models, views) bool."""
        return self.predictions == self.labels[:, None]

    @property
    def accuracy(self) -> float:
        return float(self.correct.mean())

    @property
    def chance(self) -> float:
        return 1.0 / len(self.classes)

    def per_class_accuracy(self) -> dict[str, float]:
        """Accuracy over every view of each class's test models (NaN: no test model)."""
        out = {}
        for c, name in enumerate(self.classes):
            rows = self.labels == c
            out[name] = float(self.correct[rows].mean()) if rows.any() else float("nan")
        return out

    def per_view_accuracy(self) -> np.ndarray:
        """(views,) fraction of test models classified right from each view."""
        return self.correct.mean(axis=0)

    def per_view_true_probability(self) -> np.ndarray:
        """(views,) mean probability of the true class over the test models."""
        true = np.take_along_axis(self.probabilities, self.labels[:, None, None], axis=2)[..., 0]
        return true.mean(axis=0)

    def confusion(self) -> np.ndarray:
        """Counts (C, C): row = true class, column = predicted class."""
        return confusion_matrix(
            np.repeat(self.labels, self.probabilities.shape[1]), self.predictions.ravel(),
            len(self.classes),
        )

    def summary(self) -> dict[str, object]:
        return {
            "views": self.name,
            "images": int(self.correct.size),
            "accuracy": self.accuracy,
            "chance": self.chance,
            "per_class_accuracy": self.per_class_accuracy(),
            "mean_true_probability": float(self.per_view_true_probability().mean()),
        }


def confusion_matrix(labels: np.ndarray, predictions: np.ndarray, classes: int) -> np.ndarray:
    """Counts (C, C) of (true, predicted) pairs."""
    flat = np.asarray(labels, dtype=np.int64) * classes + np.asarray(predictions, dtype=np.int64)
    return np.bincount(flat, minlength=classes * classes).reshape(classes, classes)


def write_confusion_csv(path: Path, confusion: np.ndarray, classes: Sequence[str]) -> None:
    """CSV with a header row of predicted classes and one row per true class."""
    lines = ["true\\predicted," + ",".join(classes)]
    lines += [f"{name}," + ",".join(str(int(v)) for v in row)
              for name, row in zip(classes, confusion, strict=True)]
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
