"""Figures of the classifier: training curves, confusion matrix, accuracy over the hemisphere."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rapomdp.geometry.viewsphere import azimuth_zenith
from rapomdp.io import save_png


def training_curves(rows: Sequence[dict[str, float]], path: Path) -> Path:
    """Loss and accuracy per epoch, training and validation."""
    epoch = [r["epoch"] for r in rows]
    fig = Figure(figsize=(9, 3.4))
    ax_loss, ax_acc = fig.subplots(1, 2)
    ax_loss.plot(epoch, [r["train_loss"] for r in rows], label="train")
    ax_loss.plot(epoch, [r["val_loss"] for r in rows], label="validation")
    ax_loss.set(xlabel="epoch", ylabel="cross-entropy", title="loss")
    ax_acc.plot(epoch, [r["train_accuracy"] for r in rows], label="train (augmented)")
    ax_acc.plot(epoch, [r["val_accuracy"] for r in rows], label="validation (held-out views)")
    ax_acc.set(xlabel="epoch", ylabel="accuracy", ylim=(0, 1), title="accuracy")
    ax_acc.legend(loc="lower right", fontsize=8)
    return save_png(fig, path)


def confusion_figure(confusion: np.ndarray, classes: Sequence[str], title: str,
                     path: Path) -> Path:
    """Row-normalised confusion matrix (true class per row), with the counts' share written."""
    counts = np.asarray(confusion, dtype=np.float64)
    rates = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1.0)
    n = len(classes)
    size = max(4.0, 0.42 * n + 1.5)
    fig = Figure(figsize=(size + 1.0, size))
    ax = fig.subplots()
    image = ax.imshow(rates, cmap="Blues", vmin=0.0, vmax=1.0)
    ax.set_xticks(range(n), classes, rotation=60, ha="right", fontsize=8)
    ax.set_yticks(range(n), classes, fontsize=8)
    ax.set(xlabel="predicted", ylabel="true", title=title)
    if n <= 30:
        for i, j in zip(*np.nonzero(rates >= 0.005), strict=True):
            ax.text(j, i, f"{rates[i, j]:.2f}".lstrip("0"), ha="center", va="center", fontsize=6,
                    color="white" if rates[i, j] > 0.5 else "black")
    fig.colorbar(image, ax=ax, fraction=0.046, label="fraction of the true class")
    return save_png(fig, path)


def hemisphere_figure(directions: np.ndarray, values: Sequence[np.ndarray],
                      titles: Sequence[str], suptitle: str, path: Path) -> Path:
    """Values per viewpoint on the upper hemisphere, seen from above (polar: azimuth, zenith).

    ``directions`` (V, 3) are unit vectors from the centroid to the viewpoints.
    """
    azimuth, zenith = azimuth_zenith(directions)
    zenith_deg = np.degrees(zenith)
    fig = Figure(figsize=(4.6 * len(values), 4.4))
    axes = fig.subplots(1, len(values), subplot_kw={"projection": "polar"})
    for ax, value, title in zip(np.atleast_1d(axes), values, titles, strict=True):
        points = ax.scatter(azimuth, zenith_deg, c=value, cmap="viridis", vmin=0.0, vmax=1.0,
                            s=60, edgecolors="k", linewidths=0.3)
        ax.set_ylim(0, 90)
        ax.set_yticks([30, 60, 90], ["30°", "60°", "90°"], fontsize=7)
        ax.set_title(title, fontsize=10, pad=12)
        fig.colorbar(points, ax=ax, fraction=0.046, pad=0.1)
    fig.suptitle(suptitle + "\n(seen from above; radius = angle from the zenith; "
                 "0° azimuth = +x, the models' long side)", fontsize=9, y=1.04)
    return save_png(fig, path)
