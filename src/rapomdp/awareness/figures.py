"""Figures of recognition self-awareness: calibration, Fig. 1 (depth, 2D saliency, 3D volume,
hemisphere of viewpoint scores) and Fig. 2 (one class's volume against different opponents),
each as a PNG (matplotlib, object API) and a self-contained interactive HTML page (plotly).

Panels (a)-(c) of Fig. 1 are seen from one camera, the one that took the depth image (a); the
volumes of Fig. 2 share one camera too. Every image panel has a colour bar with its unit.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.awareness.variants import RA_VARIANTS
from rapomdp.awareness.volume import SaliencyVolume
from rapomdp.geometry.viewsphere import azimuth_zenith
from rapomdp.plots import OKABE_ITO, hemisphere_axes, new_figure, save_html, save_png, style

CMAP = "inferno"
DEPTH_CMAP = "viridis_r"  # near = yellow
DEPTH_LABEL = "depth (m, along the optical axis)"
SALIENCY_LABEL = "2D saliency (0-1, unitless)"
VOXEL_LABEL = "voxel saliency (median, 0-1)"
SCORE_LABEL = "viewpoint score (Eq. 6, 0-1)"
#: The view used when a volume has no salient side (elevation, azimuth in degrees).
DEFAULT_VIEW_DEG = (20.0, -60.0)


#: calibration.json ``method`` of each fit that is a map from the viewpoint score to
#: P(correct), which calibration.png draws: one curve, or one per class.
SCORE_MAPS = {"logistic": "one", "isotonic": "one", "logistic_per_class": "per class"}
#: What the RA fits without such a map do instead (the figure draws no curve for them).
NO_SCORE_MAP = {
    "salient_view_transfer": "it pools whole confusion rows over the viewpoints that see alike "
                             "saliency",
    "logistic_score_and_viewpoint_evidence": "its P(correct) also reads the held-out "
                                             "per-viewpoint evidence",
    "held_out_mixture": "it averages the RA variants' rows with weights fitted on the held-out "
                        "labels",
}
#: The x axis of calibration.png per viewpoint score.
SCORE_AXES = {"mean": "normalised mean saliency seen (Eq. 6)",
              "area": "normalised salient area seen (Eq. 6's sum)"}


def calibration_score(variant: str) -> str:
    """The viewpoint score calibration.png bins RA variant ``variant`` by: the score its map
    reads (:data:`~rapomdp.awareness.variants.RA_VARIANTS`); ``transfer``, which reads none,
    the salient area."""
    kind = RA_VARIANTS.get(variant, ("mean", False))[0]
    return "area" if kind == "similarity" else kind


def calibration_caption(variant: str, method: str) -> str:
    """The caption of calibration.png for RA-POMDP's model ``ra_<variant>`` fitted with
    ``method`` (calibration.json's): what :func:`calibration_plot` draws for it, and no
    more."""
    model = f"ra_{variant}"
    score = calibration_score(variant)
    text = (f"Calibration on the held-out evidence: the classifier's accuracy per bin of the "
            f"{SCORE_AXES.get(score, score)} (area ~ views), and the mean P(correct) that "
            f"RA-POMDP's model ({model}) gives the same (class, viewpoint) pairs (in-sample: "
            f"it was fitted on them)")
    kind = SCORE_MAPS.get(method)
    if kind == "one":
        return text + f"; the curve is its fitted score-to-correctness map ({method})."
    if kind == "per class":
        return text + ("; the curves are its fitted score-to-correctness maps, one per class "
                       "(thin) and their mean (thick).")
    why = NO_SCORE_MAP.get(method, f"it is fitted by {method}")
    return text + f". {model} has no map from the score alone ({why}), so no curve is drawn."


def calibration_plot(scores: np.ndarray, correct: np.ndarray, calibration: Any,
                     predicted: np.ndarray | None = None, variant: str = "paper",
                     bins: int = 10) -> Any:
    """The ``matplotlib.figure.Figure`` of :func:`calibration_figure`."""
    s, y = np.asarray(scores).ravel(), np.asarray(correct, dtype=float).ravel()
    edges = np.linspace(0, 1, bins + 1)
    which = np.clip(np.digitize(s, edges) - 1, 0, bins - 1)
    count = np.bincount(which, minlength=bins)
    hits = np.bincount(which, weights=y, minlength=bins)
    centres = (edges[:-1] + edges[1:]) / 2
    model, score = f"ra_{variant}", calibration_score(variant)
    method = str(getattr(calibration, "method", ""))
    with style():
        fig = new_figure(5.5, 4.4)
        ax = fig.add_subplot()
        seen = count > 0
        ax.scatter(centres[seen], hits[seen] / count[seen],
                   s=10 + 60 * count[seen] / max(count.max(), 1), color=OKABE_ITO[4],
                   label="held-out evidence: accuracy per score bin (area ~ views)")
        if predicted is not None:
            mean_p = np.bincount(which, weights=np.asarray(predicted, float).ravel(),
                                 minlength=bins)
            ax.scatter(centres[seen], mean_p[seen] / count[seen], marker="x", s=36,
                       color=OKABE_ITO[7], linewidths=1.2, zorder=3,
                       label=f"{model}: mean predicted P(correct) per bin (in-sample)")
        grid = np.linspace(0, 1, 200)
        kind = SCORE_MAPS.get(method)
        if kind == "per class":
            curves = calibration(np.broadcast_to(grid, (len(calibration.intercepts),
                                                        grid.size)))
            for curve in curves:
                ax.plot(grid, curve, color=OKABE_ITO[5], alpha=0.25, lw=0.8)
            ax.plot(grid, curves.mean(axis=0), color=OKABE_ITO[5],
                    label=f"{model}: per-class fitted maps, class mean")
        elif kind == "one":
            ax.plot(grid, calibration(grid), color=OKABE_ITO[5],
                    label=f"{model}: fitted map ({method})")
        ax.set(xlabel=SCORE_AXES.get(score, score), ylabel="P(classifier right)", xlim=(0, 1),
               ylim=(0, 1.02), title=f"Score-to-correctness: RA-POMDP's model {model}"
               + ("" if kind else "\n(no map from the score alone: no curve)"))
        ax.grid(alpha=0.3)
        fig.legend(loc="outside lower center", fontsize=8, frameon=False)  # hides no bin
    return fig


def calibration_figure(scores: np.ndarray, correct: np.ndarray, calibration: Any,
                       path: Path, bins: int = 10, predicted: np.ndarray | None = None,
                       variant: str = "paper") -> Path:
    """Accuracy of the classifier per bin of :func:`calibration_score` on the held-out evidence
    (``scores`` and ``correct`` (N, V) at its rows' classes), RA-POMDP's model
    ``ra_<variant>``'s mean ``predicted`` P(correct) at the same pairs, and its fitted map
    where it has one (:data:`SCORE_MAPS`: a curve, or one per class);
    :func:`calibration_caption` says which."""
    with style():
        return save_png(calibration_plot(scores, correct, calibration, predicted, variant,
                                         bins), path)


# --- views ------------------------------------------------------------------------------------


def view_angles(camera_pose: np.ndarray) -> tuple[float, float]:
    """(elevation, azimuth) in degrees of the direction from the target towards the camera of a
    camera-to-world pose (4, 4) looking at it: matplotlib's ``view_init`` of that camera (both
    keep world +Z up on screen)."""
    towards_camera = -np.asarray(camera_pose, dtype=np.float64)[:3, 2]
    elevation = np.degrees(np.arcsin(np.clip(towards_camera[2], -1.0, 1.0)))
    azimuth = np.degrees(np.arctan2(towards_camera[1], towards_camera[0]))
    return float(elevation), float(azimuth)


def most_salient_view(directions: np.ndarray, scores: np.ndarray, camera_poses: np.ndarray,
                      object_pixels: np.ndarray | None = None) -> int:
    """The training view to show a class by: among the views that see the object, the one
    whose camera direction is nearest to the test viewpoint of highest score (Eq. 6: the view
    that sees the most saliency). Where every score is equal (no saliency anywhere), the view
    with the most object pixels.

    ``directions`` (V, 3) are X_rho's unit directions and ``scores`` (V,) their scores;
    ``camera_poses`` (n, 4, 4) the training views' poses; ``object_pixels`` (n,) the number of
    object pixels per view (default: every view sees the object equally).
    """
    towards = -np.asarray(camera_poses, dtype=np.float64)[:, :3, 2]
    pixels = (np.ones(towards.shape[0]) if object_pixels is None
              else np.asarray(object_pixels, dtype=np.float64))
    scores = np.asarray(scores, dtype=np.float64)
    if not np.nanmax(scores) > np.nanmin(scores) or not np.any(pixels > 0):
        return int(np.argmax(pixels))
    best = np.asarray(directions, dtype=np.float64)[int(np.nanargmax(scores))]
    return int(np.argmax(np.where(pixels > 0, towards @ best, -np.inf)))


def salient_view_angles(volume: SaliencyVolume, top_fraction: float = 0.1,
                        elevation_range_deg: tuple[float, float] = (10.0, 60.0)
                        ) -> tuple[float, float]:
    """(elevation, azimuth) in degrees of a camera facing the volume's most salient part: the
    direction from the centre of the occupied voxels to the centre of its top ``top_fraction``
    voxels by score, its elevation clipped to ``elevation_range_deg`` (a view from above, as
    the test viewpoints are). :data:`DEFAULT_VIEW_DEG` when the salient part sits at the centre
    (less than a voxel away)."""
    centres, scores = _voxels(volume)
    if scores.size == 0:
        return DEFAULT_VIEW_DEG
    top = scores >= np.quantile(scores, 1.0 - top_fraction)
    offset = centres[top].mean(axis=0) - centres.mean(axis=0)
    if np.linalg.norm(offset) < volume.grid.voxel_size_m:
        return DEFAULT_VIEW_DEG
    direction = offset / np.linalg.norm(offset)
    elevation = float(np.clip(np.degrees(np.arcsin(direction[2])), *elevation_range_deg))
    return elevation, float(np.degrees(np.arctan2(direction[1], direction[0])))


# --- panels -----------------------------------------------------------------------------------


def _voxels(volume: SaliencyVolume) -> tuple[np.ndarray, np.ndarray]:
    occupied = np.flatnonzero(~np.isnan(volume.flat_scores()))
    centres = volume.grid.indices_to_centres(volume.grid.unflat(occupied))
    return centres, volume.flat_scores()[occupied]


def _image_panel(fig: Any, ax: Any, image: np.ndarray, cmap: str, label: str, title: str,
                 vmin: float | None = None, vmax: float | None = None) -> None:
    shown = ax.imshow(image, cmap=cmap, vmin=vmin, vmax=vmax, interpolation="nearest")
    ax.set_title(title)
    ax.set_axis_off()
    # the bar beside the image itself (axes coordinates follow the equal-aspect image), not at
    # the edge of a wider cell
    fig.colorbar(shown, cax=ax.inset_axes((1.04, 0.0, 0.05, 1.0)), label=label)


def _volume_panel(fig: Any, ax: Any, volume: SaliencyVolume, title: str,
                  view_deg: tuple[float, float], colour_bar: bool = True) -> Any:
    centres, scores = _voxels(volume)
    span = (centres.max(axis=0) - centres.min(axis=0)).max() / 2 if len(centres) else 0.1
    mid = (centres.max(axis=0) + centres.min(axis=0)) / 2 if len(centres) else np.zeros(3)
    # a marker about one voxel wide: the axes span ~180 points across 2 * span metres
    side_pt = 180.0 * volume.grid.voxel_size_m / (2.0 * max(span, 1e-6))
    # painter's order: voxels far from the camera first, so the near side is drawn on top
    elevation, azimuth = np.radians(view_deg)
    towards = np.array([np.cos(elevation) * np.cos(azimuth),
                        np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    order = np.argsort(centres @ towards)
    points = ax.scatter(centres[order, 0], centres[order, 1], centres[order, 2],
                        c=scores[order], cmap=CMAP, vmin=0, vmax=1, s=max(0.5, side_pt**2),
                        marker="s", depthshade=False, linewidths=0)
    ax.set(xlim=(mid[0] - span, mid[0] + span), ylim=(mid[1] - span, mid[1] + span),
           zlim=(mid[2] - span, mid[2] + span))
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.set_proj_type("ortho")
    ax.view_init(elev=view_deg[0], azim=view_deg[1])
    ax.set_axis_off()
    ax.set_title(title)
    if colour_bar:
        fig.colorbar(points, ax=ax, shrink=0.7, label=VOXEL_LABEL)
    return points


def _hemisphere_panel(fig: Any, ax: Any, directions: np.ndarray, scores: np.ndarray,
                      camera_direction: np.ndarray | None, title: str) -> None:
    azimuth, zenith = azimuth_zenith(directions)
    points = ax.scatter(azimuth, np.degrees(zenith), c=scores, cmap=CMAP, vmin=0, vmax=1, s=28,
                        edgecolors="0.5", linewidths=0.3, zorder=2)
    best = int(np.nanargmax(scores))
    ax.scatter(azimuth[best], np.degrees(zenith[best]), s=130, facecolors="none",
               edgecolors=OKABE_ITO[1], linewidths=1.8, zorder=3, label="highest score")
    if camera_direction is not None and camera_direction[2] >= 0:
        cam_az, cam_zen = azimuth_zenith(camera_direction[None])
        ax.scatter(cam_az, np.degrees(cam_zen), marker="+", s=140, color=OKABE_ITO[2],
                   linewidths=2.0, zorder=4, label="camera of (a)-(c)")
    hemisphere_axes(ax)
    ax.set_title(title, pad=14)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.06), ncol=2, frameon=False,
              fontsize=8.5)
    fig.colorbar(points, ax=ax, shrink=0.75, pad=0.1, label=SCORE_LABEL)


def fig1_figure(depth_m: np.ndarray, saliency: np.ndarray, volume: SaliencyVolume,
                directions: np.ndarray, scores: np.ndarray, class_name: str,
                camera_pose: np.ndarray | None = None) -> Any:
    """The matplotlib figure of :func:`fig1` (a ``matplotlib.figure.Figure``)."""
    object_px = depth_m > 0
    depth = np.where(object_px, depth_m, np.nan)
    view = salient_view_angles(volume) if camera_pose is None else view_angles(camera_pose)
    towards_camera = None if camera_pose is None else -np.asarray(camera_pose)[:3, 2]
    with style():
        fig = new_figure(10.0, 7.6)
        axes = fig.subplot_mosaic([["a", "b"], ["c", "d"]],
                                  per_subplot_kw={"c": {"projection": "3d"},
                                                  "d": {"projection": "polar"}})
        _image_panel(fig, axes["a"], depth, DEPTH_CMAP, DEPTH_LABEL, "(a) depth image",
                     np.nanmin(depth) if object_px.any() else None,
                     np.nanmax(depth) if object_px.any() else None)
        _image_panel(fig, axes["b"], np.where(object_px, saliency, np.nan), CMAP,
                     SALIENCY_LABEL, "(b) 2D saliency of (a)", 0.0, 1.0)
        _volume_panel(fig, axes["c"], volume, "(c) 3D saliency volume, camera of (a)", view)
        _hemisphere_panel(fig, axes["d"], directions, scores, towards_camera,
                          "(d) viewpoint scores on X_ρ\n(top view; radius: angle from zenith)")
        fig.suptitle(f"Fig. 1: recognition self-awareness of class {class_name}")
    return fig


def fig1(depth_m: np.ndarray, saliency: np.ndarray, volume: SaliencyVolume,
         directions: np.ndarray, scores: np.ndarray, class_name: str,
         png: Path, html: Path, camera_pose: np.ndarray | None = None) -> tuple[Path, Path]:
    """Fig. 1 for one class: (a) a depth view of its volume model, (b) the 2D saliency of that
    view, (c) the 3D dense saliency volume from the camera of (a) (``camera_pose``, 4x4
    camera-to-world; default :func:`salient_view_angles`), (d) the normalised viewpoint scores
    on X_rho, seen from above. Written as a PNG and a self-contained HTML page."""
    with style():
        save_png(fig1_figure(depth_m, saliency, volume, directions, scores, class_name,
                             camera_pose), png)
    object_px = depth_m > 0
    view = salient_view_angles(volume) if camera_pose is None else view_angles(camera_pose)
    page = _fig1_page(np.where(object_px, depth_m, np.nan),
                      np.where(object_px, saliency, np.nan), volume, directions, scores,
                      class_name, view)
    return png, save_html(page, html)


def _scene_camera(view_deg: tuple[float, float], distance: float = 1.8) -> dict[str, Any]:
    elevation, azimuth = np.radians(view_deg)
    eye = distance * np.array([np.cos(elevation) * np.cos(azimuth),
                               np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    return {"eye": dict(zip("xyz", eye.tolist(), strict=True)), "up": {"x": 0, "y": 0, "z": 1},
            "projection": {"type": "orthographic"}}  # as the PNG's volume panels


def _colour_bar(title: str, x: float, y: float, length: float) -> dict[str, Any]:
    return {"title": {"text": title, "side": "right"}, "x": x, "y": y, "len": length,
            "thickness": 14}


def _volume_trace(volume: SaliencyVolume, name: str, colour_bar: dict[str, Any] | None):  # noqa: ANN202
    import plotly.graph_objects as go

    centres, scores = _voxels(volume)
    marker: dict[str, Any] = {"size": 3, "color": scores, "colorscale": "Inferno", "cmin": 0,
                              "cmax": 1, "symbol": "square", "showscale": colour_bar is not None}
    if colour_bar is not None:
        marker["colorbar"] = colour_bar
    return go.Scatter3d(x=centres[:, 0], y=centres[:, 1], z=centres[:, 2], mode="markers",
                        name=name, marker=marker, hoverinfo="text",
                        text=[f"saliency {v:.2f}" for v in scores])


def _fig1_page(depth: np.ndarray, salient: np.ndarray, volume: SaliencyVolume,
               directions: np.ndarray, scores: np.ndarray, class_name: str,
               view: tuple[float, float]) -> Any:
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    page = make_subplots(rows=2, cols=2, horizontal_spacing=0.14, vertical_spacing=0.08,
                         specs=[[{"type": "heatmap"}, {"type": "heatmap"}],
                                [{"type": "scene"}, {"type": "scene"}]],
                         subplot_titles=["(a) depth image", "(b) 2D saliency of (a)",
                                         "(c) 3D saliency volume, camera of (a)",
                                         "(d) viewpoint scores on X_ρ"])
    page.add_trace(go.Heatmap(z=depth, colorscale="Viridis", reversescale=True,
                              colorbar=_colour_bar("depth (m)", 0.43, 0.78, 0.42)), 1, 1)
    page.add_trace(go.Heatmap(z=salient, colorscale="Inferno", zmin=0, zmax=1,
                              colorbar=_colour_bar("2D saliency (0-1)", 1.0, 0.78, 0.42)),
                   1, 2)
    page.add_trace(_volume_trace(volume, "volume",
                                 _colour_bar("voxel saliency (0-1)", 0.43, 0.24, 0.42)), 2, 1)
    page.add_trace(go.Scatter3d(
        x=directions[:, 0], y=directions[:, 1], z=directions[:, 2], mode="markers",
        marker={"size": 5, "color": scores, "colorscale": "Inferno", "cmin": 0, "cmax": 1,
                "showscale": True, "colorbar": _colour_bar("viewpoint score (Eq. 6)", 1.0,
                                                           0.24, 0.42)},
        text=[f"x{i}: {s:.2f}" for i, s in enumerate(scores)], hoverinfo="text",
        name="X_rho"), 2, 2)
    for axis, anchor in (("yaxis", "x"), ("yaxis2", "x2")):
        page.layout[axis].update(autorange="reversed", scaleanchor=anchor, showticklabels=False)
    for axis in ("xaxis", "xaxis2"):
        page.layout[axis].update(showticklabels=False)
    page.update_layout(title=f"Fig. 1: recognition self-awareness, class {class_name}",
                       showlegend=False, height=1000, width=1100)
    page.update_scenes(aspectmode="data", camera=_scene_camera(view))
    return page


def fig2(volumes: Sequence[SaliencyVolume], titles: Sequence[str], class_name: str,
         png: Path, html: Path) -> tuple[Path, Path]:
    """Fig. 2: the same class's saliency volume in different classification problems, all
    seen from one camera facing the last volume's most salient part
    (:func:`salient_view_angles`), with one colour bar."""
    from plotly.subplots import make_subplots

    n = len(volumes)
    view = salient_view_angles(volumes[-1])
    with style():
        fig = new_figure(min(10.0, 2.6 * n + 1.0), 3.4)
        axes = [fig.add_subplot(1, n, i + 1, projection="3d") for i in range(n)]
        points = None
        for ax, volume, title in zip(axes, volumes, titles, strict=True):
            points = _volume_panel(fig, ax, volume, title, view, colour_bar=False)
        fig.colorbar(points, ax=axes, shrink=0.8, label=VOXEL_LABEL)
        fig.suptitle(f"Fig. 2: saliency volume of {class_name} in different classification "
                     f"problems")
        save_png(fig, png)
    page = make_subplots(rows=1, cols=n, specs=[[{"type": "scene"}] * n],
                         subplot_titles=list(titles))
    for i, volume in enumerate(volumes):
        bar = _colour_bar("voxel saliency (0-1)", 1.0, 0.5, 0.8) if i == n - 1 else None
        page.add_trace(_volume_trace(volume, titles[i], bar), 1, i + 1)
    page.update_layout(title=f"Fig. 2: saliency volume of {class_name}", showlegend=False,
                       height=520, width=min(1400, 420 * n))
    page.update_scenes(aspectmode="data", camera=_scene_camera(view))
    return png, save_html(page, html)


#: Reliability bins holding fewer outcomes than this are drawn hollow and left off the line:
#: their accuracy is a ratio of at most 4 outcomes (a display rule; nothing is fitted on it).
RELIABILITY_MIN_COUNT = 5
#: Marker styles of the reliability curves when the caller gives none: (colour, marker).
_CURVE_STYLES = tuple(zip(OKABE_ITO, "os^Dv<>P", strict=True))


def reliability_plot(curves: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
                     xlabel: str, title: str,
                     styles: dict[str, tuple[str, str]] | None = None) -> Any:
    """The ``matplotlib.figure.Figure`` of :func:`reliability_figure`: above, observed against
    predicted per bin, each marker's area proportional to its bin's count, bins of fewer than
    :data:`RELIABILITY_MIN_COUNT` outcomes hollow and off the line; below, every bin's count
    per curve, written above its bar (log scale)."""
    from matplotlib.lines import Line2D

    styles = dict(styles or {})
    largest = max([float(np.max(c[2])) for c in curves.values()] + [1.0])
    with style():
        fig = new_figure(5.8, 5.8)
        top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=(3.0, 1.5))
        top.plot([0, 1], [0, 1], color="0.6", lw=0.8, ls="--")
        handles = [Line2D([], [], color="0.6", lw=0.8, ls="--", label="perfectly calibrated")]
        n = max(len(curves), 1)
        for i, (name, (predicted, observed, count)) in enumerate(curves.items()):
            colour, marker = styles.get(name, _CURVE_STYLES[i % len(_CURVE_STYLES)])
            count = np.asarray(count, dtype=np.float64)
            seen = count > 0
            solid = count >= RELIABILITY_MIN_COUNT
            sparse = seen & ~solid
            area = 10.0 + 140.0 * count / largest
            top.plot(predicted[solid], observed[solid], color=colour, lw=1.2, zorder=2)
            top.scatter(predicted[solid], observed[solid], s=area[solid], marker=marker,
                        color=colour, edgecolors="white", linewidths=0.5, zorder=3)
            top.scatter(predicted[sparse], observed[sparse], s=area[sparse], marker=marker,
                        facecolors="none", edgecolors=colour, linewidths=1.0, alpha=0.7,
                        zorder=3)
            handles.append(Line2D([], [], color=colour, lw=1.2, marker=marker, ms=5,
                                  label=f"{name} ({int(count.sum())})"))
            bins = count.size
            x = (np.arange(bins) + (i + 0.5) / n) / bins  # the bin's share of this curve
            bottom.bar(x[seen], count[seen], width=0.9 / (bins * n), color=colour,
                       alpha=0.85)
            for xi, k in zip(x[seen], count[seen], strict=True):
                bottom.annotate(f"{int(k)}", (xi, k), xytext=(0, 1.5),
                                textcoords="offset points", ha="center", va="bottom",
                                rotation=90, fontsize=6.5, color=colour)
        handles.append(Line2D([], [], ls="", marker="o", mfc="none", mec="0.4",
                              label=f"hollow: < {RELIABILITY_MIN_COUNT} in the bin"))
        top.set(ylabel="observed accuracy on the test models", xlim=(0, 1), ylim=(0, 1.02),
                title=f"{title}\n(marker area ~ the bin's count; counts below)")
        top.grid(alpha=0.3)
        top.legend(handles=handles, loc="upper left", fontsize=8)
        bottom.set_yscale("log")
        bottom.set_ylim(0.7, largest * 8.0)
        bottom.set(xlabel=xlabel, ylabel="count per bin")
        bottom.grid(alpha=0.3, axis="y")
    return fig


def reliability_figure(curves: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]],
                       path: Path,
                       xlabel: str = "predicted P(classifier right) at (class, viewpoint)",
                       title: str = "Self-awareness on unseen objects (10 bins)",
                       styles: dict[str, tuple[str, str]] | None = None) -> Path:
    """Predicted against observed P(correct) on the test models, one curve per observation
    model (or per method): ``curves[name] = (mean predicted, observed accuracy, count)`` per
    bin (:func:`rapomdp.recognition.belief.reliability`), the counts shown
    (:func:`reliability_plot`); ``styles[name]`` = (colour, marker). Returns the path."""
    with style():
        return save_png(reliability_plot(curves, xlabel, title, styles), path)


def hemisphere_pair_figure(directions: np.ndarray, values: Sequence[np.ndarray],
                           titles: Sequence[str], suptitle: str, path: Path) -> Path:
    """Per-viewpoint values in [0, 1] side by side on the upper hemisphere seen from above
    (polar: azimuth, angle from the zenith)."""
    azimuth, zenith = azimuth_zenith(directions)
    with style():
        fig = new_figure(min(10.0, 3.3 * len(values)), 3.8)
        axes = fig.subplots(1, len(values), subplot_kw={"projection": "polar"})
        for ax, value, title in zip(np.atleast_1d(axes), values, titles, strict=True):
            points = ax.scatter(azimuth, np.degrees(zenith), c=value, cmap="viridis",
                                vmin=0.0, vmax=1.0, s=40, edgecolors="k", linewidths=0.3)
            hemisphere_axes(ax)
            ax.set_title(title, pad=12)
            fig.colorbar(points, ax=ax, fraction=0.046, pad=0.1, label="accuracy (0-1)")
        fig.suptitle(suptitle)
        return save_png(fig, path)
