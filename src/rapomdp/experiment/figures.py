"""Figures of the closed loop: Fig. 3 (belief in the true class against step) and trajectories
on the hemisphere, seen from above (matplotlib, object API, colour-blind-safe colours)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from rapomdp.config import METHOD_NAMES
from rapomdp.geometry.viewsphere import azimuth_zenith
from rapomdp.plots import (
    OKABE_ITO,
    RIGHT_COLOUR,
    WRONG_COLOUR,
    hemisphere_axes,
    new_figure,
    save_png,
    style,
)

if TYPE_CHECKING:
    from rapomdp.experiment.episode_table import EpisodeTable
    from rapomdp.experiment.metrics import TradeoffPoint

#: Each method's colour, line style and marker in every closed-loop figure (Fig. 3, the
#: trade-off, the final beliefs' reliability): Okabe-Ito colours, no two methods alike in colour
#: or marker — RA-POMDP blue, Static black — so a point drawn over another stays told apart.
METHOD_STYLES: dict[str, tuple[str, str, str]] = {
    "static": (OKABE_ITO[7], "-", "s"),
    "random": (OKABE_ITO[0], "--", "o"),
    "vptree": (OKABE_ITO[6], ":", "D"),
    "classifier": (OKABE_ITO[2], "-.", "^"),
    "ra": (OKABE_ITO[4], "-", "v"),
    "ra_class": (OKABE_ITO[1], "--", "P"),
    "blackbox": (OKABE_ITO[5], "-.", "X"),
    "learned": (OKABE_ITO[3], ":", "<"),
}
#: A method without a style of its own (greys, and markers no styled method uses).
_FALLBACK_STYLES = (("0.45", "-", "h"), ("0.6", "--", "*"), ("0.3", ":", "p"))
#: Path colours of the trajectories: Okabe-Ito without the two outcome colours.
_PATH_COLOURS = (OKABE_ITO[0], OKABE_ITO[1], OKABE_ITO[4], OKABE_ITO[6], OKABE_ITO[7],
                 OKABE_ITO[3])
WRONG_MEANS = "wrong: the declared class is not the test model's true class"


def method_style(method: str, index: int = 0) -> tuple[str, str, str]:
    """(colour, line style, marker) of ``method`` (:data:`METHOD_STYLES`; an unknown method the
    ``index``-th fallback)."""
    return METHOD_STYLES.get(method, _FALLBACK_STYLES[index % len(_FALLBACK_STYLES)])


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
    with style():
        fig = new_figure(10.0, 4.2)
        axes = fig.subplots(1, 2, sharey=True, sharex=True)
        for ax, which, title in ((axes[0], c, f"test models of class {class_name}"),
                                 (axes[1], None, f"mean over the {len(table.classes)} classes")):
            for k, (key, curve) in enumerate(belief_curves(table, methods, which).items()):
                colour, line, marker = method_style(key, k)
                ax.plot(np.arange(curve.size), curve, linestyle=line, marker=marker,
                        markersize=4, color=colour,
                        label=METHOD_NAMES.get(key, key) if ax is axes[0] else None)
            ax.set(xlabel="step (images after the first)", title=title, ylim=(0, 1.02))
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            ax.grid(alpha=0.3)
        axes[0].set_ylabel("mean belief in the true class")
        fig.legend(loc="outside lower center", ncol=min(len(methods), 5), frameon=False)
        fig.suptitle("Fig. 3: belief in the true class during exploration (an episode that "
                     "has declared keeps its final belief)")
        return save_png(fig, path)


def trajectories(table: EpisodeTable, methods: Sequence[str], class_name: str,
                 directions: np.ndarray, reachable: np.ndarray, path: Path) -> Path:
    """Each method's episodes on ``class_name`` drawn on the hemisphere, seen from above: the
    start (hollow black square), the path (one colour per episode) and the outcome at the last
    view (bluish-green disc: right; vermillion cross: wrong, see :data:`WRONG_MEANS`)."""
    c = table.classes.index(class_name)
    azimuth, zenith = azimuth_zenith(directions)
    zenith_deg = np.degrees(zenith)
    rows = -(-len(methods) // 4)
    cols = -(-len(methods) // rows)
    with style():
        fig = new_figure(10.0, 2.9 * rows + 1.1)
        axes = fig.subplots(rows, cols, subplot_kw={"projection": "polar"}, squeeze=False)
        for ax in axes.ravel()[len(methods):]:
            ax.set_visible(False)
        for ax, key in zip(axes.ravel(), methods, strict=False):
            ax.scatter(azimuth[reachable], zenith_deg[reachable], s=7, c="0.55", zorder=1)
            ax.scatter(azimuth[~reachable], zenith_deg[~reachable], s=12, c="0.75",
                       marker="x", linewidths=0.8, zorder=1)
            episodes = np.flatnonzero((table.method == key) & (table.class_index == c))
            for n, i in enumerate(episodes):
                views = table.viewpoints_of(i)
                ax.plot(azimuth[views], zenith_deg[views], "-", lw=1.4, zorder=2,
                        color=_PATH_COLOURS[n % len(_PATH_COLOURS)])
                ax.scatter(azimuth[views[0]], zenith_deg[views[0]], s=46, marker="s",
                           facecolors="none", edgecolors="black", linewidths=1.2, zorder=3)
                right = bool(table.correct[i])
                ax.scatter(azimuth[views[-1]], zenith_deg[views[-1]], zorder=4,
                           s=30 if right else 48, marker="o" if right else "X",
                           c=RIGHT_COLOUR if right else WRONG_COLOUR, edgecolors="white",
                           linewidths=0.5)
            hemisphere_axes(ax)
            ax.tick_params(axis="x", labelsize=8)
            right = int(table.correct[episodes].sum())
            ax.set_title(f"{METHOD_NAMES.get(key, key)}: {right}/{episodes.size} right")
        handles = [
            Line2D([], [], ls="", marker="o", ms=4, color="0.55", label="reachable viewpoint"),
            Line2D([], [], ls="", marker="x", ms=5, color="0.75", label="unreachable"),
            Line2D([], [], ls="", marker="s", ms=7, mfc="none", mec="black", label="start"),
            Line2D([], [], color=_PATH_COLOURS[0], lw=1.4, label="path (colour: episode)"),
            Line2D([], [], ls="", marker="o", ms=6, color=RIGHT_COLOUR, label="last view: right"),
            Line2D([], [], ls="", marker="X", ms=7, color=WRONG_COLOUR, label="last view: wrong"),
        ]
        spare = axes.ravel()[len(methods):]
        if spare.size:  # the legend in the first empty panel, else below the panels
            spare[0].set_visible(True)
            spare[0].set_axis_off()
            spare[0].legend(handles=handles, loc="center", frameon=False)
        else:
            fig.legend(handles=handles, loc="outside lower center", ncol=3, frameon=False)
        fig.suptitle(f"Trajectories on the test models of class {class_name}, seen from above "
                     f"(rings: angle from the zenith)\n{WRONG_MEANS}")
        return save_png(fig, path)


def tradeoff(points: Sequence[TradeoffPoint], path: Path,
             ylabel: str = "accuracy (95 % CI)", title: str = "Accuracy against energy") -> Path:
    """:func:`tradeoff_plot` written as a PNG; returns the path."""
    with style():
        return save_png(tradeoff_plot(points, ylabel, title), path)


def tradeoff_plot(points: Sequence[TradeoffPoint], ylabel: str = "accuracy (95 % CI)",
                  title: str = "Accuracy against energy") -> Any:
    """Accuracy against mean movement energy: one curve per method over its settings (POMDPs:
    the wrong-declaration cost λ; Random: its stop belief), Static one point; Table 1's
    settings ringed; the error bars are what ``ylabel`` says (the points' low and high).

    Each method has its own colour and marker (:func:`method_style`); a method of one point
    (Static) is drawn above the curves as a large hollow marker, so that it and a curve's point
    at the same place (a POMDP that declares at once) both stay visible. Returns the
    ``matplotlib.figure.Figure``."""
    with style():
        fig = new_figure(7.0, 4.8)
        ax = fig.subplots()
        for i, key in enumerate(dict.fromkeys(p.method for p in points)):
            mine = sorted((p for p in points if p.method == key),
                          key=lambda p: p.summary.means["energy"])
            energy = np.array([p.summary.means["energy"] for p in mine])
            accuracy = np.array([p.summary.accuracy for p in mine])
            errors = np.maximum(  # never below 0, whatever rounding does at 0 % or 100 %
                np.array([[p.summary.accuracy - p.summary.accuracy_low for p in mine],
                          [p.summary.accuracy_high - p.summary.accuracy for p in mine]]), 0.0)
            colour, line, marker = method_style(key, i)
            single = len(mine) == 1
            ax.errorbar(energy, accuracy, yerr=errors, linestyle=line, marker=marker,
                        markersize=11 if single else 5, capsize=4 if single else 2,
                        color=colour, markerfacecolor="none" if single else colour,
                        markeredgewidth=1.8 if single else 1.0, zorder=4 if single else 2,
                        label=METHOD_NAMES.get(key, key))
            for p, x, y in zip(mine, energy, accuracy, strict=True):
                if p.configured and not single:  # a method of one point: that is Table 1's
                    ax.plot(x, y, marker="o", markersize=12, fillstyle="none", color=colour)
                if p.parameter != "none":
                    ax.annotate(f"{p.value:g}", (x, y), textcoords="offset points",
                                xytext=(5, -10), fontsize=9, color=colour)
        ax.set(xlabel="mean movement energy per episode (m)", ylabel=ylabel,
               title=f"{title} (labels: λ in m; Random: stop belief; ring: Table 1)")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right")
    return fig
