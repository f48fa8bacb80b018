"""A labelled contact sheet: one depth render per model, one row per class."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from rapomdp.data.dataset import Dataset
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import Intrinsics, look_at
from rapomdp.io import atomic_path


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
    """Write the sheet; each tile is titled with the model's id and role."""
    by_class = {c: [m for m in dataset.models if m.class_name == c] for c in dataset.classes}
    rows = len(by_class)
    cols = max(len(models) for models in by_class.values())
    fig = Figure(figsize=(1.9 * cols, 1.55 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    for ax in axes.ravel():
        ax.axis("off")
    for r, (class_name, models) in enumerate(by_class.items()):
        for c, model in enumerate(models):
            pose = preview_pose(model.centroid, radius_m, elevation_deg, azimuth_deg)
            depth = DepthRenderer(dataset.mesh(model), intrinsics).render(pose)
            shown = np.ma.masked_equal(depth, 0.0)
            ax = axes[r, c]
            ax.imshow(shown, cmap="viridis_r", interpolation="nearest")
            ax.set_title(f"{model.id} ({model.role})", fontsize=7)
            if c == 0:
                ax.text(-0.08, 0.5, class_name, transform=ax.transAxes, rotation=90,
                        ha="right", va="center", fontsize=9, fontweight="bold")
    fig.suptitle(
        f"{len(dataset.models)} models, {rows} classes: depth from elevation "
        f"{elevation_deg:.0f} deg, radius {radius_m} m (near = yellow)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - 0.35 / rows))
    out_png = Path(out_png)
    with atomic_path(out_png) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    return out_png
