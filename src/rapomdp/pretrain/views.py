"""The corpus's network inputs: every model rendered over the whole viewsphere, preprocessed.

Each model is normalised as the dataset stage normalises (upright, bounding-sphere radius
``dataset.radius_m``), rendered by the pipeline's renderer and camera from ``views``
near-uniform directions at the training radius, and preprocessed by the one
:func:`~rapomdp.recognition.preprocess.preprocess` with one draw of the training augmentation
(crop shift and scale), so the backbone sees depth exactly as the pipeline's classifier does.
The inputs are kept as float16 (n, 1, S, S) in one ``views.npz``: with thousands of models the
raw images would not fit in memory, the inputs do (about 8 KB a view at 64 px).

Example:
    >>> from rapomdp.pretrain.views import ViewSettings
    >>> ViewSettings().views, ViewSettings().input_size_px
    (24, 64)
"""

from __future__ import annotations

import hashlib
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from rapomdp.config import AugmentConfig, NoiseConfig, PreprocessConfig
from rapomdp.data.layouts import MESH_EXTENSIONS
from rapomdp.data.meshes import centroid, load_mesh, normalise_mesh
from rapomdp.data.renderer import DepthRenderer
from rapomdp.geometry.camera import look_at_many, xtion_intrinsics
from rapomdp.geometry.viewsphere import viewpoints
from rapomdp.io import ArtefactError, load_npz, save_npz
from rapomdp.parallel import TaskReport, run_tasks
from rapomdp.recognition.preprocess import PreprocessParams
from rapomdp.recognition.training import augmented_inputs

VIEWS_FILE = "views.npz"


@dataclass(frozen=True)
class ViewSettings:
    """How the corpus is seen: the pipeline's defaults (camera, radii, preprocessing).

    Attributes:
        views: directions per model over the whole sphere.
        radius_m: camera distance, metres (``render.radius_m``).
        object_radius_m: bounding-sphere radius after normalisation (``dataset.radius_m``).
        width_px, height_px: the camera's image (``camera``).
        input_size_px, crop_size_m, depth_range_m, background, fit_margin: the preprocessing
            (``train.preprocess``).
        shift, scale: the augmentation's ranges (``train.augment``).
        seed: the augmentation's seed.
    """

    views: int = 24
    radius_m: float = 0.6
    object_radius_m: float = 0.2
    width_px: int = 160
    height_px: int = 120
    input_size_px: int = PreprocessConfig().input_size_px
    crop_size_m: float = PreprocessConfig().crop_size_m
    depth_range_m: float = PreprocessConfig().depth_range_m
    background: float = PreprocessConfig().background
    fit_margin: float = PreprocessConfig().fit_margin
    shift: float = AugmentConfig().shift
    scale: float = AugmentConfig().scale
    seed: int = 0

    @property
    def preprocessing(self) -> PreprocessParams:
        """The classifier's preprocessing these inputs were made with."""
        return PreprocessParams(self.input_size_px, self.crop_size_m, self.depth_range_m,
                                self.background, self.fit_margin)


@dataclass(frozen=True)
class CorpusViews:
    """``views.npz``: inputs (n, 1, S, S) float16, their class ``labels`` (n,), ``models``
    (n,) model numbers, the ``classes`` and the ``model_names`` (``class/model``)."""

    inputs: np.ndarray
    labels: np.ndarray
    models: np.ndarray
    classes: list[str]
    model_names: list[str]


def corpus_models(corpus: Path) -> list[tuple[str, Path]]:
    """Every (class, mesh file) of a corpus folder, sorted.

    Args:
        corpus: a ``generic``-layout mesh folder (``<class>/<model>.<ext>``).

    Returns:
        The pairs, classes and files in name order.
    """
    if not corpus.is_dir():
        raise ArtefactError(f"{corpus}: no corpus folder (build it: rapomdp pretrain)")
    return [(class_dir.name, path)
            for class_dir in sorted(p for p in corpus.iterdir() if p.is_dir())
            for path in sorted(class_dir.iterdir()) if path.suffix.lower() in MESH_EXTENSIONS]


def _render_share(files: list[Path], numbers: list[int], settings: ViewSettings,
                  report: TaskReport) -> np.ndarray:
    """The inputs (len(files) * views, 1, S, S) float16 of a share of the models."""
    intrinsics = xtion_intrinsics(settings.width_px, settings.height_px)
    augment = AugmentConfig(shift=settings.shift, scale=settings.scale)
    out = []
    for path, number in zip(files, numbers, strict=True):
        mesh = normalise_mesh(load_mesh(path), settings.object_radius_m)
        centre = centroid(mesh.vertices)
        eyes = viewpoints(settings.views, settings.radius_m, centre=centre)
        depth = DepthRenderer(mesh, intrinsics).render(look_at_many(eyes, centre))
        rng = np.random.default_rng([settings.seed, number])
        out.append(augmented_inputs(depth, augment, NoiseConfig(), rng, intrinsics.fx,
                                    intrinsics.fy, settings.preprocessing).astype(np.float16))
        report(1)
    return np.concatenate(out) if out else np.zeros(
        (0, 1, settings.input_size_px, settings.input_size_px), np.float16)


def settings_digest(corpus: Path, settings: ViewSettings) -> str:
    """A digest of the corpus's file list and the settings (a changed corpus is re-rendered)."""
    listing = "\n".join(f"{c}/{p.name}:{p.stat().st_size}" for c, p in corpus_models(corpus))
    return hashlib.sha256((listing + repr(asdict(settings))).encode()).hexdigest()[:16]


def render_corpus(corpus: Path, out: Path, settings: ViewSettings, workers: int = 1,
                  progress: bool = True) -> CorpusViews:
    """Render and preprocess every corpus model into ``out/views.npz`` (kept when the corpus
    and the settings are unchanged).

    Args:
        corpus: the corpus folder.
        out: the pretraining folder.
        settings: how the models are seen.
        workers: processes rendering shares of the models.
        progress: a progress bar.

    Returns:
        The views.
    """
    path = out / VIEWS_FILE
    digest = settings_digest(corpus, settings)
    if path.is_file():
        stored = load_npz(path, keys=("digest",))
        if str(stored["digest"]) == digest:
            return load_corpus_views(path)
    models = corpus_models(corpus)
    if not models:
        raise ArtefactError(f"{corpus}: the corpus holds no mesh")
    classes = sorted({c for c, _ in models})
    shares = [list(map(int, s)) for s in
              np.array_split(np.arange(len(models)), min(len(models), 8 * max(1, workers)))]
    parts = run_tasks(_render_share, [([models[i][1] for i in s], s, settings) for s in shares],
                      workers, "pretrain: corpus views", progress, unit="models",
                      sizes=[len(s) for s in shares], reports=True)
    labels = np.repeat([classes.index(c) for c, _ in models], settings.views).astype(np.int64)
    numbers = np.repeat(np.arange(len(models)), settings.views).astype(np.int64)
    save_npz(path, inputs=np.concatenate(parts), labels=labels, models=numbers,
             classes=np.array(classes), model_names=np.array([f"{c}/{p.stem}" for c, p in models]),
             digest=np.array(digest))
    return load_corpus_views(path)


def load_corpus_views(path: Path) -> CorpusViews:
    """Read ``views.npz``.

    Args:
        path: the file.

    Returns:
        The views.
    """
    data = load_npz(path)
    return CorpusViews(data["inputs"], data["labels"], data["models"],
                       [str(c) for c in data["classes"]], [str(m) for m in data["model_names"]])
