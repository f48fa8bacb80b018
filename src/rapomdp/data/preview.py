"""A labelled contact sheet: one depth render per model, one row per class (matplotlib,
object API)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rapomdp.data.dataset import Dataset
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import Intrinsics, look_at
from rapomdp.plots import save_png, style

#: A tile's width and height in inches (its title included).
TILE_IN = (1.9, 1.55)


def preview_pose(centre: np.ndarray, radius_m: float, elevation_deg: float,
                 azimuth_deg: float) -> np.ndarray:
    """The look-at pose from a direction given in degrees (elevation above the floor)."""
    el, az = np.radians(elevation_deg), np.radians(azimuth_deg)
    direction = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    return look_at(centre + radius_m * direction, centre)


def contact_sheet(
    dataset: Dataset,
    intrinsics: Intrinsics,
    out_png: str | Path,
    radius_m: float = 0.6,
    elevation_deg: float = 30.0,
    azimuth_deg: float = -60.0,
) -> Path:
    """Write the sheet; each tile is titled with the model's id and role. A camera that is not
    finite (or ``elevation_deg`` outside [-90, 90]) is a ValueError: it would draw blank tiles."""
    for name, value in (("radius_m", radius_m), ("elevation_deg", elevation_deg),
                        ("azimuth_deg", azimuth_deg)):
        if not math.isfinite(value):
            raise ValueError(f"contact sheet: {name} must be finite, got {value}")
    if radius_m <= 0 or not -90.0 <= elevation_deg <= 90.0:
        raise ValueError(f"contact sheet: radius {radius_m} m must be positive and elevation "
                         f"{elevation_deg} in [-90, 90] degrees")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    by_class = {c: [m for m in dataset.models if m.class_name == c] for c in dataset.classes}
    rows = len(by_class)
    cols = max(len(models) for models in by_class.values())
    with style():
        # one tile per model: the sheet grows with the dataset (it is not shown in the report);
        # fixed margins in inches, since a constrained layout of hundreds of tiles took most of
        # the sheet's time (the tiles, titles and labels do not change size)
        width_in, height_in = TILE_IN[0] * cols + 1.2, TILE_IN[1] * rows + 0.5
        fig = Figure(figsize=(width_in, height_in))
        FigureCanvasAgg(fig)
        left, right = 0.35 / width_in, 1.0 - 0.85 / width_in
        bottom, top = 0.05 / height_in, 1.0 - 0.6 / height_in
        axes = fig.subplots(rows, cols, squeeze=False, gridspec_kw={
            "left": left, "right": right, "bottom": bottom, "top": top,
            "wspace": 0.06, "hspace": 0.32})
        for ax in axes.ravel():
            ax.set_axis_off()
            # hidden axes too: the layout then skips their (undrawn) ticks; the same sheet
            ax.xaxis.set_visible(False)
            ax.yaxis.set_visible(False)
        shown = None
        near, far = np.inf, 0.0
        images = {}
        for r, models in enumerate(by_class.values()):
            for c, model in enumerate(models):
                pose = preview_pose(model.centroid, radius_m, elevation_deg, azimuth_deg)
                depth = DepthRenderer(dataset.mesh(model), intrinsics).render(pose)
                images[r, c] = np.ma.masked_equal(depth, 0.0)
                if images[r, c].count():
                    near = min(near, float(images[r, c].min()))
                    far = max(far, float(images[r, c].max()))
        for r, (class_name, models) in enumerate(by_class.items()):
            for c, model in enumerate(models):
                ax = axes[r, c]
                shown = ax.imshow(images[r, c], cmap="viridis_r", interpolation="nearest",
                                  vmin=near if far > 0 else None, vmax=far if far > 0 else None)
                ax.set_title(f"{model.id} ({model.role})", fontsize=7)
                if c == 0:
                    ax.text(-0.08, 0.5, class_name, transform=ax.transAxes, rotation=90,
                            ha="right", va="center", fontsize=9, fontweight="bold")
        if shown is not None:
            bar_h = min(0.9, 3.0 / rows) * (top - bottom)
            bar = fig.add_axes((right + 0.2 / width_in, (top + bottom - bar_h) / 2,
                                0.15 / width_in, bar_h))
            fig.colorbar(shown, cax=bar, label="depth (m)")
        fig.suptitle(f"{len(dataset.models)} models, {rows} classes: depth from elevation "
                     f"{elevation_deg:.0f}°, radius {radius_m} m", y=1.0 - 0.12 / height_in,
                     va="top")
        return save_png(fig, Path(out_png), dpi=110)
