"""The robot figure: the hemisphere coloured by manipulability, the arm in a few solutions
(matplotlib, object API; equal 3D aspect; legend below the axes)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rapomdp.plots import OKABE_ITO, new_figure, save_png, style

#: The arm's colours (blue, orange, reddish purple): none is the unreachable marker's black
#: nor on the manipulability colour map (viridis).
ARM_COLOURS = (OKABE_ITO[4], OKABE_ITO[0], OKABE_ITO[6])
UNREACHABLE_COLOUR = "black"


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
    with style():
        _plot_robot(path, viewpoints_m, reachable, manipulability, centroid_m, base_m,
                    skeletons_m, camera_poses, title, arm_labels)


def _plot_robot(path: str | Path, viewpoints_m: np.ndarray, reachable: np.ndarray,
                manipulability: np.ndarray, centroid_m: np.ndarray, base_m: np.ndarray,
                skeletons_m: list[np.ndarray], camera_poses: np.ndarray, title: str,
                arm_labels: list[str] | None) -> None:
    figure = new_figure(10.0, 5.6)
    figure.get_layout_engine().set(wspace=0.08)
    ax3d = figure.add_subplot(1, 2, 1, projection="3d")
    ax2d = figure.add_subplot(1, 2, 2)
    good = np.asarray(reachable, dtype=bool)
    values = np.asarray(manipulability, dtype=np.float64)
    vmin = float(np.nanmin(values[good])) if good.any() else 0.0
    vmax = float(np.nanmax(values[good])) if good.any() else 1.0
    colour_args = {"c": values[good], "cmap": "viridis", "vmin": vmin, "vmax": vmax}

    scatter = ax3d.scatter(*viewpoints_m[good].T, s=16, depthshade=False, **colour_args,
                           label=f"reachable viewpoint ({int(good.sum())})")
    ax3d.scatter(*viewpoints_m[~good].T, marker="x", color=UNREACHABLE_COLOUR, s=18,
                 linewidths=1.0, label=f"unreachable ({int((~good).sum())})")
    ax3d.scatter(*centroid_m, marker="*", color=OKABE_ITO[5], s=90, label="object centroid")
    ax3d.scatter(*base_m, marker="s", color="0.45", s=60, label="arm base")
    for k, (points, pose) in enumerate(zip(skeletons_m, camera_poses, strict=True)):
        colour = ARM_COLOURS[k % len(ARM_COLOURS)]
        label = arm_labels[k] if arm_labels else None
        ax3d.plot(*points.T, "-o", color=colour, markersize=3, linewidth=2.5, label=label)
        axis = np.stack([pose[:3, 3], pose[:3, 3] + 0.12 * pose[:3, 2]])
        ax3d.plot(*axis.T, color=colour, linewidth=1, linestyle="--")
    everything = np.concatenate([viewpoints_m, [centroid_m, base_m], *skeletons_m])
    low, high = everything.min(axis=0), everything.max(axis=0)
    middle, half = (low + high) / 2, float((high - low).max()) / 2
    ax3d.set_xlim(middle[0] - half, middle[0] + half)
    ax3d.set_ylim(middle[1] - half, middle[1] + half)
    ax3d.set_zlim(0.0, 2 * half)
    # equal limits and box: one metre is one metre; zoomed out so the z label stays inside
    ax3d.set_box_aspect((1.0, 1.0, 1.0), zoom=0.82)
    ax3d.set_xlabel("x (m)")
    ax3d.set_ylabel("y (m)")
    ax3d.set_zlabel("z (m)")
    ax3d.view_init(elev=22, azim=-60)
    ax3d.set_title("3D view (dashed: camera axis)")

    ax2d.scatter(*viewpoints_m[good, :2].T, s=36, **colour_args)
    ax2d.scatter(*viewpoints_m[~good, :2].T, marker="x", color=UNREACHABLE_COLOUR, s=30)
    ax2d.scatter(*centroid_m[:2], marker="*", color=OKABE_ITO[5], s=90)
    ax2d.scatter(*base_m[:2], marker="s", color="0.45", s=60)
    for k, points in enumerate(skeletons_m):
        ax2d.plot(*points[:, :2].T, "-", color=ARM_COLOURS[k % len(ARM_COLOURS)], linewidth=2)
    ax2d.set_aspect("equal")
    ax2d.set_xlabel("x (m)")
    ax2d.set_ylabel("y (m)")
    ax2d.set_title("top view")
    ax2d.grid(alpha=0.3)
    figure.colorbar(scatter, ax=ax2d, shrink=0.8,
                    label=r"manipulability $\sqrt{\det(J J^\top)}$")
    handles, labels = ax3d.get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside lower center", ncol=3, frameon=False)
    if title:
        figure.suptitle(title)
    save_png(figure, path)
