"""Figures of the classifier: training curves, confusion matrix, accuracy over the hemisphere
(matplotlib, object API)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rapomdp.geometry.viewsphere import azimuth_zenith
from rapomdp.plots import MAX_WIDTH_IN, hemisphere_axes, new_figure, save_png, style

__all__ = ["confusion_figure", "hemisphere_figure", "save_png", "training_curves"]


def training_curves(rows: Sequence[dict[str, float]], path: Path) -> Path:
    """Loss and accuracy per epoch, training and validation (each ensemble member's own
    lines, fainter after the first, when ``rows`` hold a ``member`` column)."""
    from matplotlib.ticker import MaxNLocator

    members = sorted({int(r.get("member", 0)) for r in rows})
    with style():
        fig = new_figure(9.0, 3.6)
        ax_loss, ax_acc = fig.subplots(1, 2)
        for member in members:
            mine = [r for r in rows if int(r.get("member", 0)) == member]
            epoch = [r["epoch"] for r in mine]
            first = member == members[0]
            look = {"alpha": 1.0 if first else 0.45, "ms": 3}
            ax_loss.plot(epoch, [r["train_loss"] for r in mine], "-o", color="C0",
                         label="train" if first else None, **look)
            ax_loss.plot(epoch, [r["val_loss"] for r in mine], "--s", color="C1",
                         label="validation" if first else None, **look)
            ax_acc.plot(epoch, [r["train_accuracy"] for r in mine], "-o", color="C0",
                        label="train (augmented)" if first else None, **look)
            ax_acc.plot(epoch, [r["val_accuracy"] for r in mine], "--s", color="C1",
                        label="validation (held-out views)" if first else None, **look)
        suffix = f" ({len(members)} ensemble members)" if len(members) > 1 else ""
        ax_loss.set(xlabel="epoch", ylabel="cross-entropy (nats)", title="Loss" + suffix)
        ax_loss.legend(loc="upper right")
        ax_acc.set(xlabel="epoch", ylabel="accuracy", ylim=(0, 1.02), title="Accuracy" + suffix)
        ax_acc.legend(loc="lower right")
        for ax in (ax_loss, ax_acc):
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax.grid(alpha=0.3)
        return save_png(fig, path)


def confusion_figure(confusion: np.ndarray, classes: Sequence[str], title: str,
                     path: Path) -> Path:
    """Row-normalised confusion matrix (true class per row), each cell's share written (from
    9 pt for a few classes down to 7 pt for 30; beyond 30 classes only the colours)."""
    counts = np.asarray(confusion, dtype=np.float64)
    rates = counts / np.maximum(counts.sum(axis=1, keepdims=True), 1.0)
    n = len(classes)
    size = min(MAX_WIDTH_IN - 1.2, max(4.5, 0.3 * n + 2.5))  # the colour bar takes 1.2 in
    cell_pt = 72.0 * (size - 2.0) / max(n, 1)  # about the cell's side in points
    with style():
        fig = new_figure(size + 1.2, size)
        ax = fig.add_subplot()
        image = ax.imshow(rates, cmap="Blues", vmin=0.0, vmax=1.0)
        tick_pt = float(np.clip(cell_pt * 0.6, 6.5, 9.0))
        ax.set_xticks(range(n), classes, rotation=60, ha="right", fontsize=tick_pt)
        ax.set_yticks(range(n), classes, fontsize=tick_pt)
        ax.set(xlabel="predicted class", ylabel="true class", title=title)
        if n <= 30:
            text_pt = float(np.clip(cell_pt * 0.4, 7.0, 10.0))
            for i, j in zip(*np.nonzero(rates >= 0.005), strict=True):
                ax.text(j, i, f"{rates[i, j]:.2f}".lstrip("0"), ha="center", va="center",
                        fontsize=text_pt, color="white" if rates[i, j] > 0.5 else "black")
        fig.colorbar(image, ax=ax, shrink=0.8, label="fraction of the true class's images")
        return save_png(fig, path)


def hemisphere_figure(directions: np.ndarray, values: Sequence[np.ndarray],
                      titles: Sequence[str], suptitle: str, path: Path,
                      label: str = "fraction (0-1)") -> Path:
    """Values in [0, 1] per viewpoint on the upper hemisphere, seen from above (polar: azimuth,
    zenith). ``directions`` (V, 3) are unit vectors from the centroid to the viewpoints;
    ``label`` names the colour bar's quantity and unit."""
    azimuth, zenith = azimuth_zenith(directions)
    zenith_deg = np.degrees(zenith)
    count = len(values)
    with style():
        fig = new_figure(min(10.0, 4.4 * count + 0.6), 4.6)
        axes = np.atleast_1d(fig.subplots(1, count, subplot_kw={"projection": "polar"}))
        points = None
        for ax, value, title in zip(axes, values, titles, strict=True):
            points = ax.scatter(azimuth, zenith_deg, c=value, cmap="viridis", vmin=0.0,
                                vmax=1.0, s=50, edgecolors="k", linewidths=0.3)
            hemisphere_axes(ax)
            ax.set_title(title, pad=20)
        fig.colorbar(points, ax=list(axes), shrink=0.8, label=label)
        fig.suptitle(suptitle + "\n(seen from above; radius: angle from the zenith; "
                     "+x is the models' long side)")
        return save_png(fig, path)
