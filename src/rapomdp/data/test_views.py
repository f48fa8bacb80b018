"""A dataset model seen from the test viewpoints X_rho: the one place test views are rendered.

The observe, classifier_eval and vptree stages render every model at all of X_rho at once, with
the sensor noise drawn from a stream keyed by the seed, a purpose and the model
(:func:`xrho_noise_rng`): the volume models under :data:`VOLUME_STREAM`, the test models under
:data:`TEST_STREAM`, so that every stage that classifies a test model at X_rho sees the same
images. The closed loop renders one viewpoint at a time (:meth:`TestViews.look`) with the
episode's own generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rapomdp.config import Config, NoiseConfig
from rapomdp.data.dataset import Dataset, ModelEntry
from rapomdp.data.renderer import DepthRenderer
from rapomdp.data.splits import class_seed
from rapomdp.data.training_views import model_poses, render_depth
from rapomdp.geometry.camera import xtion_intrinsics

#: The noise stream of the volume models' renders at X_rho (the observation models' evidence).
VOLUME_STREAM = "observe/volume"
#: The noise stream of the test models' renders at X_rho (single-view accuracy, quality tables).
TEST_STREAM = "classifier_eval"
#: The noise stream of the training models the cross-fitted classifiers label at X_rho.
CROSSFIT_STREAM = "crossfit"


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
    def of_model(cls, config: Config, dataset: Dataset, model: ModelEntry) -> TestViews:
        """A dataset model seen from X_rho (``config.viewpoints``) by the configured camera,
        with the configured sensor noise (``config.render.noise``)."""
        intrinsics = xtion_intrinsics(config.camera.width, config.camera.height)
        vp = config.viewpoints
        return cls(DepthRenderer(dataset.mesh(model), intrinsics),
                   model_poses(model, vp.count, vp.radius_m, hemisphere=True),
                   config.render.noise)

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


def xrho_renders(dataset: Dataset, model: ModelEntry, config: Config,
                 purpose: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Clean depth, sensor depth (noise when enabled) and poses of a model at X_rho, the noise
    drawn from ``purpose``'s stream (:data:`VOLUME_STREAM` or :data:`TEST_STREAM`)."""
    views = TestViews.of_model(config, dataset, model)
    clean, sensed = views.render_all(xrho_noise_rng(config.seed, purpose, model))
    return clean, sensed, views.poses
