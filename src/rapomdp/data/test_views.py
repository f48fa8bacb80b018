"""A dataset model seen from the test viewpoints X_rho: the one place test views are rendered.

The ``xrho`` stage renders every volume and test model at all of X_rho once, with the sensor
noise drawn from a stream keyed by the seed, a purpose and the model (:func:`xrho_noise_rng`):
the volume models under :data:`VOLUME_STREAM`, the test models under :data:`TEST_STREAM`. The
classifier_eval, observe and vptree stages read those images (:class:`XrhoViews`), so every
stage that classifies a model at X_rho sees the same images and none renders them again. The
closed loop renders one viewpoint at a time (:meth:`TestViews.look`) with the episode's own
generator.

``W/xrho/``: ``xrho.json`` (the models, their roles and noise streams) and
``views/<class>/<model>.npz`` with ``depth`` (V, H, W) float32 metres as the sensor sees it,
``poses`` (V, 4, 4) camera-to-world and, only when the sensor noise is on, ``clean`` (V, H, W).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rapomdp.config import CameraConfig, Config, NoiseConfig, ViewpointsConfig
from rapomdp.context import RunContext
from rapomdp.data.dataset import Dataset, ModelEntry, load_dataset
from rapomdp.data.renderer import DepthRenderer
from rapomdp.data.splits import class_seed
from rapomdp.data.training_views import model_poses, render_depth
from rapomdp.geometry.camera import xtion_intrinsics
from rapomdp.io import load_npz, read_json, save_npz, write_json_atomic
from rapomdp.parallel import run_tasks
from rapomdp.workspace import StageError, StageInputs

#: The noise stream of the volume models' renders at X_rho (the observation models' evidence).
VOLUME_STREAM = "observe/volume"
#: The noise stream of the test models' renders at X_rho (single-view accuracy, quality tables).
TEST_STREAM = "classifier_eval"
#: The noise stream of each role the xrho stage renders.
ROLE_STREAMS = {"volume": VOLUME_STREAM, "test": TEST_STREAM}
XRHO_FILE = "xrho.json"


def xrho_noise_rng(seed: int, purpose: str, model: ModelEntry) -> np.random.Generator:
    """The sensor-noise generator of one model's renders at X_rho for ``purpose``."""
    return class_seed(seed, f"{purpose}/{model.class_name}/{model.id}")


@dataclass
class TestViews:
    """A test model at the workspace centre, seen from the test viewpoints ``poses`` (V, 4, 4)
    by ``renderer`` with the sensor noise ``noise``."""

    __test__ = False  # not a pytest class, whatever its name

    renderer: DepthRenderer
    poses: np.ndarray
    noise: NoiseConfig

    @classmethod
    def of_model(cls, dataset: Dataset, model: ModelEntry,
                 viewpoints: ViewpointsConfig | None = None, camera: CameraConfig | None = None,
                 noise: NoiseConfig | None = None) -> TestViews:
        """A dataset model seen from X_rho by the camera, with the sensor noise.

        Args:
            dataset: The dataset ``model`` belongs to (its mesh is read).
            model: The model, placed at the workspace centre.
            viewpoints: The ``viewpoints`` section: X_rho's count V and radius in metres
                (None: the defaults).
            camera: The ``camera`` section: the depth image's width and height in pixels
                (None: the defaults).
            noise: The ``render.noise`` section: the sensor noise (None: off).

        Returns:
            The model's :class:`TestViews`: ``poses`` (V, 4, 4) camera-to-world in metres.
        """
        viewpoints = ViewpointsConfig() if viewpoints is None else viewpoints
        camera = CameraConfig() if camera is None else camera
        intrinsics = xtion_intrinsics(camera.width, camera.height)
        return cls(DepthRenderer(dataset.mesh(model), intrinsics),
                   model_poses(model, viewpoints.count, viewpoints.radius_m, hemisphere=True),
                   NoiseConfig() if noise is None else noise)

    def look(self, viewpoint: int, rng: np.random.Generator) -> np.ndarray:
        """The sensor's depth image (H, W) in metres from ``viewpoint``."""
        return render_depth(self.renderer, self.poses[viewpoint : viewpoint + 1], self.noise,
                            rng)[0]

    def sensed(self, rng: np.random.Generator) -> np.ndarray:
        """The sensor's depth images (V, H, W) from every viewpoint."""
        return render_depth(self.renderer, self.poses, self.noise, rng)

    def render_all(self, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Clean and sensed depth (V, H, W) from every viewpoint; one array when noise is off."""
        clean = self.renderer.render(self.poses)
        return clean, (self.sensed(rng) if self.noise.enabled else clean)


def xrho_renders(dataset: Dataset, model: ModelEntry, purpose: str, seed: int = 0,
                 viewpoints: ViewpointsConfig | None = None, camera: CameraConfig | None = None,
                 noise: NoiseConfig | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A model rendered at every test viewpoint X_rho, the sensor noise (when on) drawn from
    ``purpose``'s stream (:func:`xrho_noise_rng`).

    Args:
        dataset: The dataset ``model`` belongs to.
        model: The model.
        purpose: The noise stream (:data:`VOLUME_STREAM` or :data:`TEST_STREAM`).
        seed: The configuration's ``seed`` (keys the noise stream).
        viewpoints: The ``viewpoints`` section (None: the defaults).
        camera: The ``camera`` section (None: the defaults).
        noise: The ``render.noise`` section (None: off).

    Returns:
        The clean depth (V, H, W) in metres, the sensor's depth (V, H, W) in metres (the same
        array when the noise is off) and the camera poses (V, 4, 4) camera-to-world.
    """
    views = TestViews.of_model(dataset, model, viewpoints, camera, noise)
    clean, sensed = views.render_all(xrho_noise_rng(seed, purpose, model))
    return clean, sensed, views.poses


def _view_file(root: Path, model: ModelEntry) -> Path:
    return root / "views" / model.class_name / f"{model.id}.npz"


def _render_xrho_model(dataset: Dataset, model: ModelEntry, seed: int,
                       viewpoints: ViewpointsConfig, camera: CameraConfig, noise: NoiseConfig,
                       out: Path) -> None:
    """One model's renders at X_rho, written to ``out`` (a task of the xrho stage)."""
    clean, sensed, poses = xrho_renders(dataset, model, ROLE_STREAMS[model.role], seed,
                                        viewpoints, camera, noise)
    extra = {"clean": clean} if noise.enabled else {}
    save_npz(_view_file(out, model), compressed=True, depth=sensed, poses=poses, **extra)


def run_xrho_stage(config: Config, inputs: StageInputs, out: Path, context: RunContext) -> None:
    """Render every volume and test model at X_rho once, one model per task over the worker
    processes (each model's noise has its own stream: the images do not depend on them).

    Args:
        config: the run's configuration; the stage reads ``seed``, ``camera``, ``render``
            and ``viewpoints``.
        inputs: the folders of the stages it reads (dataset).
        out: the stage's temporary folder; the workspace swaps it in when the stage finishes.
        context: worker processes, threads and progress bars (no artefact depends on them).

    Returns:
        None. Writes into ``out``: ``views/<class>/<model>.npz`` (depth images (V, H, W) in metres
            at the V test viewpoints, and their poses) and ``xrho.json``.
    """
    dataset = load_dataset(inputs.dataset)
    models = [m for m in dataset.models if m.role in ROLE_STREAMS]
    run_tasks(_render_xrho_model,
              [(dataset, m, config.seed, config.viewpoints, config.camera, config.render.noise,
                out) for m in models],
              context.worker_count, "xrho: the volume and test models at X_rho",
              context.progress, context.scheduler, unit="models", pool=context.pool)
    vp = config.viewpoints
    write_json_atomic(out / XRHO_FILE, {
        "viewpoints": vp.count, "radius_m": vp.radius_m, "noise": config.render.noise.enabled,
        "models": [{"class": m.class_name, "id": m.id, "role": m.role,
                    "stream": ROLE_STREAMS[m.role]} for m in models]})


@dataclass(frozen=True)
class XrhoImages:
    """One model at X_rho: what the sensor saw (V, H, W), the noiseless depth (the same array
    when the noise is off) and the camera poses (V, 4, 4)."""

    sensed: np.ndarray
    clean: np.ndarray
    poses: np.ndarray


@dataclass(frozen=True)
class XrhoViews:
    """The xrho stage's images, read back per model."""

    root: Path
    dataset: Dataset

    def load(self, model: ModelEntry) -> XrhoImages:
        """``model``'s images at X_rho; a model the stage did not render is a StageError."""
        if model.role not in ROLE_STREAMS:
            raise StageError(f"{self.root}: no X_rho images of {model.class_name}/{model.id} "
                             f"(a {model.role} model); the xrho stage renders the volume and "
                             "test models only")
        arrays = load_npz(_view_file(self.root, model))
        sensed = arrays["depth"]
        return XrhoImages(sensed, arrays["clean"] if "clean" in arrays else sensed,
                          arrays["poses"])


def load_xrho_views(xrho_dir: str | Path, dataset: Dataset | str | Path) -> XrhoViews:
    """The xrho stage's output in ``xrho_dir`` (``dataset``: the dataset stage's folder, or
    the dataset already loaded from it), checked to be a finished stage."""
    xrho_dir = Path(xrho_dir)
    read_json(xrho_dir / XRHO_FILE)  # a missing or broken record is named here
    return XrhoViews(xrho_dir, dataset if isinstance(dataset, Dataset)
                     else load_dataset(dataset))
