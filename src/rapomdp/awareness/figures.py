"""Figures of recognition self-awareness: calibration, Fig. 1 (depth, 2D saliency, 3D volume,
hemisphere of viewpoint scores) and Fig. 2 (one class's volume against different opponents),
each as a PNG (matplotlib) and an interactive HTML page (plotly)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rapomdp.awareness.observation import ClassScoreCalibration, ScoreCalibration
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.geometry.viewsphere import azimuth_zenith
from rapomdp.io import atomic_path, save_png

CMAP = "inferno"


def _save_html(fig, path: Path) -> Path:  # noqa: ANN001 - a plotly Figure
    with atomic_path(path) as tmp:
        fig.write_html(str(tmp), include_plotlyjs="cdn", full_html=True)
    return path


def calibration_figure(scores: np.ndarray, correct: np.ndarray,
                       calibration: object,
                       path: Path, bins: int = 10) -> Path:
    """Accuracy of the classifier per score bin on the held-out evidence, and the fitted map
    (a curve per class for a per-class fit; none for a fit on more than the score)."""
    s, y = np.asarray(scores).ravel(), np.asarray(correct, dtype=float).ravel()
    edges = np.linspace(0, 1, bins + 1)
    which = np.clip(np.digitize(s, edges) - 1, 0, bins - 1)
    count = np.bincount(which, minlength=bins)
    hits = np.bincount(which, weights=y, minlength=bins)
    centres = (edges[:-1] + edges[1:]) / 2
    fig = Figure(figsize=(5, 3.6))
    ax = fig.subplots()
    seen = count > 0
    ax.scatter(centres[seen], hits[seen] / count[seen], s=10 + 40 * count[seen] / count.max(),
               label="held-out evidence: accuracy per score bin")
    grid = np.linspace(0, 1, 200)
    if isinstance(calibration, ClassScoreCalibration):  # one curve per class
        curves = calibration(np.broadcast_to(grid, (len(calibration.intercepts), grid.size)))
        for curve in curves:
            ax.plot(grid, curve, color="C3", alpha=0.25, lw=0.8)
        ax.plot(grid, curves.mean(axis=0), color="C3", label="per-class fit (RA), class mean")
    elif isinstance(calibration, ScoreCalibration):
        ax.plot(grid, calibration(grid), color="C3", label=f"{calibration.method} fit (RA)")
    ax.set(xlabel="normalised viewpoint saliency score (Eq. 6)", ylabel="P(classifier right)",
           ylim=(0, 1.02), title="score -> P(correct) calibration")
    ax.legend(fontsize=8)
    return save_png(fig, path)


def _voxels(volume: SaliencyVolume) -> tuple[np.ndarray, np.ndarray]:
    occupied = np.flatnonzero(~np.isnan(volume.flat_scores()))
    centres = volume.grid.indices_to_centres(volume.grid.unflat(occupied))
    return centres, volume.flat_scores()[occupied]


def _volume_axes(ax, volume: SaliencyVolume, title: str) -> None:  # noqa: ANN001
    centres, scores = _voxels(volume)
    span = (centres.max(axis=0) - centres.min(axis=0)).max() / 2 if len(centres) else 0.1
    mid = (centres.max(axis=0) + centres.min(axis=0)) / 2 if len(centres) else np.zeros(3)
    # a marker about one voxel wide: the axes span ~220 points across 2 * span metres
    side_pt = 220.0 * volume.grid.voxel_size_m / (2.0 * max(span, 1e-6))
    order = np.argsort(scores)  # salient voxels drawn last, on top
    ax.scatter(centres[order, 0], centres[order, 1], centres[order, 2], c=scores[order],
               cmap=CMAP, vmin=0, vmax=1, s=max(0.5, side_pt**2), marker="s", depthshade=False,
               linewidths=0)
    ax.set(xlim=(mid[0] - span, mid[0] + span), ylim=(mid[1] - span, mid[1] + span),
           zlim=(mid[2] - span, mid[2] + span), title=title)
    ax.view_init(elev=20, azim=-60)
    ax.set_axis_off()


def _volume_trace(volume: SaliencyVolume, name: str, show_scale: bool = True):  # noqa: ANN202
    import plotly.graph_objects as go

    centres, scores = _voxels(volume)
    return go.Scatter3d(
        x=centres[:, 0], y=centres[:, 1], z=centres[:, 2], mode="markers", name=name,
        marker={"size": 3, "color": scores, "colorscale": "Inferno", "cmin": 0, "cmax": 1,
                "symbol": "square", "showscale": show_scale},
        text=[f"saliency {v:.2f}" for v in scores], hoverinfo="text",
    )


def fig1(depth_m: np.ndarray, saliency: np.ndarray, volume: SaliencyVolume,
         directions: np.ndarray, scores: np.ndarray, class_name: str,
         png: Path, html: Path) -> tuple[Path, Path]:
    """Fig. 1 for one class: (a) a depth view of its volume model, (b) the 2D saliency of that
    view, (c) the 3D dense saliency volume, (d) the normalised viewpoint scores on X_rho."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    fig = Figure(figsize=(15, 3.8))
    ax = fig.add_subplot(1, 4, 1)
    shown = np.where(depth_m > 0, depth_m, np.nan)
    ax.imshow(shown, cmap="viridis_r")
    ax.set(title=f"(a) depth, {class_name}")
    ax.set_axis_off()
    ax = fig.add_subplot(1, 4, 2)
    ax.imshow(np.where(depth_m > 0, saliency, np.nan), cmap=CMAP, vmin=0, vmax=1)
    ax.set(title="(b) 2D saliency")
    ax.set_axis_off()
    _volume_axes(fig.add_subplot(1, 4, 3, projection="3d"), volume, "(c) 3D saliency volume")
    ax = fig.add_subplot(1, 4, 4, projection="polar")
    azimuth, zenith = azimuth_zenith(directions)
    zenith = np.degrees(zenith)
    points = ax.scatter(azimuth, zenith, c=scores, cmap=CMAP, vmin=0, vmax=1, s=30)
    ax.set(title="(d) viewpoint scores (Eq. 6)", ylim=(0, 90))
    fig.colorbar(points, ax=ax, fraction=0.046, label="normalised score")
    save_png(fig, png)

    page = make_subplots(rows=1, cols=4, specs=[[{"type": "heatmap"}, {"type": "heatmap"},
                                                 {"type": "scene"}, {"type": "scene"}]],
                         subplot_titles=["(a) depth", "(b) 2D saliency", "(c) 3D volume",
                                         "(d) viewpoint scores"])
    page.add_trace(go.Heatmap(z=shown[::-1], colorscale="Viridis", reversescale=True,
                              showscale=False), 1, 1)
    page.add_trace(go.Heatmap(z=np.where(depth_m > 0, saliency, np.nan)[::-1],
                              colorscale="Inferno", zmin=0, zmax=1, showscale=False), 1, 2)
    page.add_trace(_volume_trace(volume, "volume", show_scale=False), 1, 3)
    page.add_trace(go.Scatter3d(
        x=directions[:, 0], y=directions[:, 1], z=directions[:, 2], mode="markers",
        marker={"size": 5, "color": scores, "colorscale": "Inferno", "cmin": 0, "cmax": 1,
                "showscale": True}, text=[f"x{i}: {s:.2f}" for i, s in enumerate(scores)],
        hoverinfo="text", name="X_rho"), 1, 4)
    page.update_layout(title=f"Fig. 1: recognition self-awareness, class {class_name}",
                       showlegend=False, height=480, width=1600)
    page.update_scenes(aspectmode="data")
    return png, _save_html(page, html)


def fig2(volumes: Sequence[SaliencyVolume], titles: Sequence[str], class_name: str,
         png: Path, html: Path) -> tuple[Path, Path]:
    """Fig. 2: the same class's saliency volume in different classification problems."""
    from plotly.subplots import make_subplots

    n = len(volumes)
    fig = Figure(figsize=(4 * n, 4))
    for i, (volume, title) in enumerate(zip(volumes, titles, strict=True)):
        _volume_axes(fig.add_subplot(1, n, i + 1, projection="3d"), volume, title)
    fig.suptitle(f"Fig. 2: saliency volume of {class_name} against different classes")
    save_png(fig, png)
    page = make_subplots(rows=1, cols=n, specs=[[{"type": "scene"}] * n],
                         subplot_titles=list(titles))
    for i, volume in enumerate(volumes):
        page.add_trace(_volume_trace(volume, titles[i], show_scale=i == n - 1), 1, i + 1)
    page.update_layout(title=f"Fig. 2: saliency volume of {class_name}", showlegend=False,
                       height=520, width=420 * n)
    page.update_scenes(aspectmode="data")
    return png, _save_html(page, html)


def reliability_figure(curves: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
                       path: Path) -> Path:
    """Predicted against observed P(correct) on the test models, one line per observation
    model: ``curves[name] = (mean predicted, observed accuracy, count)`` per bin."""
    fig = Figure(figsize=(5, 4))
    ax = fig.subplots()
    ax.plot([0, 1], [0, 1], color="0.6", lw=0.8, ls="--", label="perfectly calibrated")
    for i, (name, (predicted, observed, count)) in enumerate(curves.items()):
        seen = count > 0
        ax.plot(predicted[seen], observed[seen], marker="o", ms=3, color=f"C{i}", label=name)
    ax.set(xlabel="predicted P(classifier right) at (class, viewpoint)",
           ylabel="observed accuracy on the test models", xlim=(0, 1), ylim=(0, 1.02),
           title="self-awareness on unseen objects (10 bins)")
    ax.legend(fontsize=7)
    return save_png(fig, path)


def hemisphere_pair_figure(directions: np.ndarray, values: Sequence[np.ndarray],
                           titles: Sequence[str], suptitle: str, path: Path) -> Path:
    """Per-viewpoint values in [0, 1] side by side on the upper hemisphere seen from above
    (polar: azimuth, angle from the zenith)."""
    azimuth, zenith = azimuth_zenith(directions)
    fig = Figure(figsize=(4.2 * len(values), 4.2))
    axes = fig.subplots(1, len(values), subplot_kw={"projection": "polar"})
    for ax, value, title in zip(np.atleast_1d(axes), values, titles, strict=True):
        points = ax.scatter(azimuth, np.degrees(zenith), c=value, cmap="viridis", vmin=0.0,
                            vmax=1.0, s=50, edgecolors="k", linewidths=0.3)
        ax.set_ylim(0, 90)
        ax.set_yticks([30, 60, 90], ["30°", "60°", "90°"], fontsize=7)
        ax.set_title(title, fontsize=9, pad=12)
        fig.colorbar(points, ax=ax, fraction=0.046, pad=0.1)
    fig.suptitle(suptitle, fontsize=9, y=1.03)
    return save_png(fig, path)
