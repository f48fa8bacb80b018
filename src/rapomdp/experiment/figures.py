"""Figures of the closed loop: Fig. 3 (belief in the true class against step), trajectories
on the hemisphere seen from above, and accuracy against energy over the λ sweep."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from rapomdp.experiment.config import METHOD_NAMES  # noqa: E402
from rapomdp.geometry.viewsphere import azimuth_zenith  # noqa: E402
from rapomdp.recognition.figures import save_png  # noqa: E402

if TYPE_CHECKING:
    from rapomdp.experiment.evaluation import EpisodeTable
    from rapomdp.experiment.metrics import TradeoffPoint


def belief_curves(table: EpisodeTable, methods: Sequence[str], class_index: int | None
                  ) -> dict[str, np.ndarray]:
    """Mean belief in the true class after each image (index 0: the start view), per method.

    An episode that has declared keeps its final belief for the later steps, so every curve
    averages the same episodes at every step. ``class_index`` None averages over all classes.
    """
    curves = {}
    for key in methods:
        sel = table.method == key
        if class_index is not None:
            sel &= table.class_index == class_index
        idx = np.flatnonzero(sel)
        if idx.size == 0:
            continue
        traces = [table.beliefs_in_true_class(i) for i in idx]
        length = max(t.size for t in traces)
        padded = np.stack([np.pad(t, (0, length - t.size), mode="edge") for t in traces])
        curves[key] = padded.mean(axis=0)
    return curves


def fig3(table: EpisodeTable, methods: Sequence[str], class_name: str, path: Path) -> Path:
    """Fig. 3: belief in the true class against step for ``class_name`` and over all classes."""
    c = table.classes.index(class_name)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True)
    for ax, which, title in ((axes[0], c, f"class {class_name}"),
                             (axes[1], None, f"mean over {len(table.classes)} classes")):
        for key, curve in belief_curves(table, methods, which).items():
            ax.plot(np.arange(curve.size), curve, marker="o", markersize=3,
                    label=METHOD_NAMES.get(key, key))
        ax.set(xlabel="step (images after the first)", title=title, ylim=(0, 1.02))
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("belief in the true class")
    axes[1].legend(loc="lower right", fontsize=8)
    fig.suptitle("Belief evolution during exploration (declared episodes keep their final "
                 "belief)", fontsize=10)
    return save_png(fig, path)


def trajectories(table: EpisodeTable, methods: Sequence[str], class_name: str,
                 directions: np.ndarray, reachable: np.ndarray, path: Path) -> Path:
    """Each method's episodes on ``class_name`` drawn on the hemisphere, seen from above:
    start (circle), moves (line), last view (green if the declaration was right, red if not)."""
    c = table.classes.index(class_name)
    azimuth, zenith = azimuth_zenith(directions)
    zenith_deg = np.degrees(zenith)
    fig, axes = plt.subplots(1, len(methods), subplot_kw={"projection": "polar"},
                             figsize=(3.6 * len(methods), 4.0))
    colours = plt.get_cmap("tab10")
    for ax, key in zip(np.atleast_1d(axes), methods, strict=True):
        ax.scatter(azimuth[reachable], zenith_deg[reachable], s=8, c="0.6", zorder=1)
        ax.scatter(azimuth[~reachable], zenith_deg[~reachable], s=10, c="0.8", marker="x",
                   zorder=1)
        episodes = np.flatnonzero((table.method == key) & (table.class_index == c))
        for n, i in enumerate(episodes):
            views = table.viewpoints_of(i)
            colour = colours(n % 10)
            ax.plot(azimuth[views], zenith_deg[views], "-", color=colour, lw=1.2, zorder=2)
            ax.scatter(azimuth[views[0]], zenith_deg[views[0]], s=36, facecolors="none",
                       edgecolors=colour, linewidths=1.5, zorder=3)
            ax.scatter(azimuth[views[-1]], zenith_deg[views[-1]], s=22, zorder=4,
                       c="tab:green" if table.correct[i] else "tab:red")
        ax.set_ylim(0, 90)
        ax.set_yticks([30, 60, 90], ["30°", "60°", "90°"], fontsize=7)
        ax.set_xticklabels([])
        right = int(table.correct[episodes].sum())
        ax.set_title(f"{METHOD_NAMES.get(key, key)}\n{right}/{episodes.size} right", fontsize=9)
    fig.suptitle(f"Trajectories on {class_name} (seen from above; radius = angle from the "
                 "zenith; grey x: unreachable; ring: start; dot: last view, green = right)",
                 fontsize=9)
    return save_png(fig, path)


def tradeoff(points: Sequence[TradeoffPoint], path: Path) -> Path:
    """Accuracy against mean movement energy: one curve per method over its settings (POMDPs:
    the wrong-declaration cost λ; Random: its stop belief), Static one point; Table 1's
    settings ringed."""
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    for key in dict.fromkeys(p.method for p in points):
        mine = sorted((p for p in points if p.method == key),
                      key=lambda p: p.summary.means["energy"])
        energy = np.array([p.summary.means["energy"] for p in mine])
        accuracy = np.array([p.summary.accuracy for p in mine])
        errors = np.array([[p.summary.accuracy - p.summary.accuracy_low for p in mine],
                           [p.summary.accuracy_high - p.summary.accuracy for p in mine]])
        line = ax.errorbar(energy, accuracy, yerr=errors, marker="o", markersize=4, capsize=2,
                           label=METHOD_NAMES.get(key, key))
        for p, x, y in zip(mine, energy, accuracy, strict=True):
            if p.configured:
                ax.plot(x, y, marker="o", markersize=10, fillstyle="none",
                        color=line[0].get_color())
            if p.parameter != "none":
                ax.annotate(f"{p.value:g}", (x, y), textcoords="offset points", xytext=(4, -9),
                            fontsize=6, color=line[0].get_color())
    ax.set(xlabel="mean movement energy per episode (m)", ylabel="accuracy",
           title="Accuracy against energy (labels: λ in m, Random: stop belief; ring: Table 1)")
    ax.title.set_fontsize(9)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="lower right")
    return save_png(fig, path)
