"""The robot figure: the hemisphere coloured by manipulability, the arm in a few solutions."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from rapomdp.io import atomic_path


def pick_poses(manipulability: np.ndarray, reachable: np.ndarray, count: int = 3) -> np.ndarray:
    """Indices of reachable viewpoints to draw the arm at: the most and least manipulable and
    ones between (by manipulability rank)."""
    index = np.flatnonzero(reachable)
    if index.size == 0:
        return index
    order = index[np.argsort(manipulability[index], kind="stable")]
    picks = np.linspace(0, order.size - 1, min(count, order.size)).round().astype(int)
    return order[np.unique(picks)][::-1]


def plot_robot(
    path: str | Path,
    viewpoints_m: np.ndarray,
    reachable: np.ndarray,
    manipulability: np.ndarray,
    centroid_m: np.ndarray,
    base_m: np.ndarray,
    skeletons_m: list[np.ndarray],
    camera_poses: np.ndarray,
    title: str = "",
    arm_labels: list[str] | None = None,
) -> None:
    """Write a PNG: 3D view (arm drawn at a few solutions) and a top view of the hemisphere.

    ``skeletons_m`` holds, per drawn solution, the world points (k, 3) of the link frames and
    the camera; ``camera_poses`` (len(skeletons_m), 4, 4) the camera-to-world poses there.
    """
    figure = Figure(figsize=(13, 6), dpi=110)
    FigureCanvasAgg(figure)
    ax3d = figure.add_subplot(1, 2, 1, projection="3d")
    ax2d = figure.add_subplot(1, 2, 2)
    figure.subplots_adjust(left=0.02, right=0.88, wspace=0.12)
    good = np.asarray(reachable, dtype=bool)
    values = np.asarray(manipulability, dtype=np.float64)
    vmin = float(np.nanmin(values[good])) if good.any() else 0.0
    vmax = float(np.nanmax(values[good])) if good.any() else 1.0
    colour_args = {"c": values[good], "cmap": "viridis", "vmin": vmin, "vmax": vmax}

    scatter = ax3d.scatter(*viewpoints_m[good].T, s=18, depthshade=False, **colour_args)
    ax3d.scatter(*viewpoints_m[~good].T, marker="x", color="tab:red", s=18,
                 label=f"unreachable ({int((~good).sum())})")
    ax3d.scatter(*centroid_m, marker="*", color="black", s=80, label="object centroid")
    ax3d.scatter(*base_m, marker="s", color="tab:gray", s=60, label="arm base")
    for k, (points, pose) in enumerate(zip(skeletons_m, camera_poses, strict=True)):
        label = arm_labels[k] if arm_labels else None
        ax3d.plot(*points.T, "-o", color=f"C{k + 1}", markersize=3, linewidth=2.5, label=label)
        axis = np.stack([pose[:3, 3], pose[:3, 3] + 0.12 * pose[:3, 2]])
        ax3d.plot(*axis.T, color=f"C{k + 1}", linewidth=1, linestyle="--")
    everything = np.concatenate([viewpoints_m, [centroid_m, base_m], *skeletons_m])
    low, high = everything.min(axis=0), everything.max(axis=0)
    middle, half = (low + high) / 2, float((high - low).max()) / 2
    ax3d.set_xlim(middle[0] - half, middle[0] + half)
    ax3d.set_ylim(middle[1] - half, middle[1] + half)
    ax3d.set_zlim(0.0, 2 * half)
    ax3d.set_box_aspect((1.0, 1.0, 1.0))
    ax3d.set_xlabel("x (m)")
    ax3d.set_ylabel("y (m)")
    ax3d.set_zlabel("z (m)")
    ax3d.view_init(elev=22, azim=-60)
    ax3d.legend(loc="upper left", fontsize=7)

    ax2d.scatter(*viewpoints_m[good, :2].T, s=40, **colour_args)
    ax2d.scatter(*viewpoints_m[~good, :2].T, marker="x", color="tab:red", s=30)
    ax2d.scatter(*centroid_m[:2], marker="*", color="black", s=80)
    ax2d.scatter(*base_m[:2], marker="s", color="tab:gray", s=60)
    for k, points in enumerate(skeletons_m):
        ax2d.plot(*points[:, :2].T, "-", color=f"C{k + 1}", linewidth=2)
    ax2d.set_aspect("equal")
    ax2d.set_xlabel("x (m)")
    ax2d.set_ylabel("y (m)")
    ax2d.set_title("top view (x: unreachable)", fontsize=9)
    colour_axes = figure.add_axes((0.91, 0.15, 0.015, 0.7))
    figure.colorbar(scatter, cax=colour_axes, label="manipulability sqrt(det(J J^T))")
    if title:
        figure.suptitle(title, fontsize=10)
    with atomic_path(path) as tmp:
        figure.savefig(tmp, format="png")
