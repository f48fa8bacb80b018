"""The render stage: depth images of every model over the training viewsphere.

The training views are near-uniform over the *whole* sphere around each model's centroid (the
paper: unrelated to the test viewpoints). Only the object is rendered, with no floor: a real
pipeline segments the floor away first. Output (``W/render/``): ``render.json`` (intrinsics,
views) and ``views/<class>/<model>.npz`` with ``depth`` (views, H, W) float32 metres and
``poses`` (views, 4, 4) camera-to-world.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.config import Config, NoiseConfig, RenderConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, load_dataset
from rapomdp.data.noise import apply_sensor_noise
from rapomdp.data.renderer import DepthRenderer, incidence_angles
from rapomdp.data.splits import class_seed
from rapomdp.geometry.camera import Intrinsics, look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints
from rapomdp.io import load_npz, read_json, save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.workspace import StageInputs

RENDER_FILE = "render.json"


def model_poses(model: ModelEntry, count: int, radius_m: float, hemisphere: bool) -> np.ndarray:
    """Look-at poses (count, 4, 4) on a viewsphere around the model's centroid."""
    eyes = viewpoints(count, radius_m, hemisphere=hemisphere, centre=model.centroid)
    return look_at_many(eyes, model.centroid)


def render_depth(
    renderer: DepthRenderer,
    poses: np.ndarray,
    noise: NoiseConfig,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Depth images for poses, with the sensor noise when ``noise.enabled``."""
    if not noise.enabled:
        return renderer.render(poses)
    depth, faces = renderer.render_faces(poses)
    angles = incidence_angles(renderer, poses, faces)
    return apply_sensor_noise(depth, angles, noise, rng or np.random.default_rng())


def _render_model(dataset: Dataset, model: ModelEntry, intrinsics: Intrinsics,
                  cfg: RenderConfig, seed: int, out: Path) -> None:
    """One model's training-viewsphere renders, written to ``out`` (a task of the stage)."""
    renderer = DepthRenderer(dataset.mesh(model), intrinsics)
    poses = model_poses(model, cfg.views, cfg.radius_m, hemisphere=False)
    rng = class_seed(seed, f"render/{model.class_name}/{model.id}")
    depth = render_depth(renderer, poses, cfg.noise, rng)
    save_npz(out / "views" / model.class_name / f"{model.id}.npz", compressed=True,
             depth=depth, poses=poses)


def run_render_stage(config: Config, inputs: StageInputs, out: Path,
                     context: RunContext) -> None:
    """Render every model of the dataset from the training viewsphere, one model per task
    over the worker processes (each model's noise has its own seed: the images do not depend
    on the number of processes).

    Args:
        config: the run's configuration; the stage reads ``seed``, ``camera`` and ``render``.
        inputs: the folders of the stages it reads (dataset).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``views/<class>/<model>.npz`` (depth images (n, H, W) in metres
            over the training viewsphere, and their poses) and ``render.json``.
    """
    dataset = load_dataset(inputs.dataset)
    intrinsics = xtion_intrinsics(config.camera.width, config.camera.height)
    cfg = config.render
    run_tasks(_render_model, [(dataset, m, intrinsics, cfg, config.seed, out)
                              for m in dataset.models],
              context.worker_count, "render: training viewsphere", context.progress,
              context.scheduler, unit="models", pool=context.pool)
    write_json_atomic(
        out / RENDER_FILE,
        {"intrinsics": intrinsics.to_dict(), "views": cfg.views, "radius_m": cfg.radius_m,
         "noise": cfg.noise.model_dump()},
    )


@dataclass
class TrainingViews:
    """The render stage's output, read back lazily per model."""

    root: Path
    intrinsics: Intrinsics
    dataset: Dataset

    def load(self, model: ModelEntry) -> tuple[np.ndarray, np.ndarray]:
        """Depth images (views, H, W) and poses (views, 4, 4) of one model."""
        arrays = load_npz(self.root / "views" / model.class_name / f"{model.id}.npz")
        return arrays["depth"], arrays["poses"]


def load_training_views(render_dir: str | Path, dataset_dir: str | Path) -> TrainingViews:
    render_dir = Path(render_dir)
    info = read_json(render_dir / RENDER_FILE)
    return TrainingViews(render_dir, Intrinsics(**info["intrinsics"]), load_dataset(dataset_dir))
