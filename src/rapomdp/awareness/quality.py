"""Self-awareness quality: how well an observation model predicts whether the classifier is
right on unseen (test) models at each viewpoint.

For every test model of class c and viewpoint x the classifier outputs label o; a model gives
P(o | c, x) and P(correct) = P(c | c, x). Reported: the mean log-likelihood of the actual labels,
the Brier score of correctness, the AUC of P(correct) for separating right from wrong, the mean
predicted P(correct) against the actual accuracy.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
from sklearn.metrics import roc_auc_score

from rapomdp.awareness.artefacts import QUALITY_COLUMNS
from rapomdp.awareness.observation import ObservationModel
from rapomdp.document import markdown_table
from rapomdp.io import atomic_path


def roc_auc(scores: np.ndarray, positive: np.ndarray) -> float:
    """Area under the ROC curve (scikit-learn's; ties count half); NaN with one class only."""
    scores = np.asarray(scores, dtype=np.float64).reshape(-1)
    positive = np.asarray(positive, dtype=bool).reshape(-1)
    if positive.all() or not positive.any():
        return float("nan")
    return float(roc_auc_score(positive, scores))


def quality_from_probabilities(p_observed: np.ndarray, p_correct: np.ndarray,
                               correct: np.ndarray) -> dict[str, float]:
    """The table's measures from per-outcome P(observed label), P(correct) and rightness."""
    p_observed, p_correct = np.ravel(p_observed), np.ravel(p_correct)
    correct = np.ravel(correct).astype(bool)
    return {
        "log_likelihood": float(np.mean(np.log(np.maximum(p_observed, 1e-300)))),
        "brier": float(np.mean((p_correct - correct) ** 2)),
        "auc": roc_auc(p_correct, correct),
        "mean_p_correct": float(p_correct.mean()),
        "accuracy": float(correct.mean()),
    }


def awareness_quality(model: ObservationModel, true_labels: np.ndarray,
                      predicted: np.ndarray) -> dict[str, float]:
    """Quality of ``model`` on test outcomes: true labels (M,), predicted labels (M, V)."""
    true_labels = np.asarray(true_labels)
    predicted = np.asarray(predicted)
    p = model.probabilities
    if predicted.shape[1] != p.shape[0]:
        raise ValueError(f"{predicted.shape[1]} viewpoints of outcomes, model has {p.shape[0]}")
    x = np.broadcast_to(np.arange(p.shape[0])[None], predicted.shape)
    t = np.broadcast_to(true_labels[:, None], predicted.shape)
    return quality_from_probabilities(p[x, t, predicted], p[x, t, t], predicted == t)


def quality_table(models: dict[str, ObservationModel], true_labels: np.ndarray,
                  predicted: np.ndarray) -> list[dict[str, float | str]]:
    return [{"model": name, **awareness_quality(m, true_labels, predicted)}
            for name, m in models.items()]


def write_quality(rows: list[dict[str, float | str]], csv_path: Path, md_path: Path) -> None:
    """The table as CSV and as a markdown table."""
    with atomic_path(csv_path) as tmp, open(tmp, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(QUALITY_COLUMNS))
        writer.writeheader()
        writer.writerows(rows)
    with atomic_path(md_path) as tmp:
        tmp.write_text(markdown_table(*quality_cells(rows)))


def quality_cells(rows: list[dict[str, float | str]]) -> tuple[list[str], list[list[str]]]:
    """The self-awareness table's header and cells (the markdown file and the report)."""
    header = ["model", "log-likelihood / obs. (higher better)", "Brier (lower better)", "AUC",
              "mean P(correct)", "test accuracy"]
    return header, [[str(r["model"]), *(f"{float(r[k]):.3f}" for k in QUALITY_COLUMNS[1:])]
                    for r in rows]
