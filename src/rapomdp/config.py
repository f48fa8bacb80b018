"""The validated configuration: one YAML file, a default for every value, unknown keys refused.

Units: metres and degrees at this surface (``*_m``, ``*_deg``); the code converts to radians.
Each top-level section belongs to the stages that read it, and a stage's cache key hashes only
the sections it reads.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Literal

import yaml
from pydantic import BaseModel, Field, ValidationError, model_validator

from rapomdp.experiment.config import EvaluateConfig
from rapomdp.robot.config import RobotConfig
from rapomdp.section import Section


class ConfigError(ValueError):
    """The configuration file is unreadable or holds a wrong key or value (named)."""


class SplitConfig(Section):
    """Models per class for each role, and what becomes of a class's models beyond their total
    (a folder with more): ``train`` adds them to the training models, ``drop`` leaves them out.
    Default 4 / 1 / 4: 4 test models a class for paired statistics over test models (the
    paper's 3 / 1 / 1 is ``configs/paper.yaml``)."""

    train: int = Field(4, ge=1)
    volume: int = Field(1, ge=1)
    test: int = Field(4, ge=1)
    extra: Literal["train", "drop"] = "train"

    @property
    def total(self) -> int:
        return self.train + self.volume + self.test


class DatasetConfig(Section):
    """Where the meshes come from and how they are normalised and split."""

    source: Literal["procedural", "folder"] = "procedural"
    path: Path | None = Field(None, description="mesh folder (source: folder)")
    layout: Literal["auto", "generic", "objectnet3d", "modelnet", "shapenet"] = "auto"
    up_axis: Literal["auto", "x", "y", "z", "-x", "-y", "-z"] = Field(
        "auto", description="the meshes' up axis; auto = the layout's convention"
    )
    synset_map: Path | None = Field(None, description="ShapeNet synset-to-name JSON")
    classes: list[str] | None = Field(None, description="use only these classes")
    models_per_class: int | None = Field(
        None, ge=1, description="procedural models per class (default: the split's total)"
    )
    radius_m: float = Field(0.2, gt=0, description="bounding-sphere radius after normalisation")
    split: SplitConfig = SplitConfig()
    too_few_models: Literal["error", "drop"] = "error"

    @model_validator(mode="after")
    def _folder_needs_path(self) -> DatasetConfig:
        if self.source == "folder" and self.path is None:
            raise ValueError("source 'folder' needs dataset.path")
        if self.models_per_class is not None and self.models_per_class < self.split.total:
            raise ValueError(
                f"models_per_class ({self.models_per_class}) is below the split's total "
                f"({self.split.total})"
            )
        return self


class CameraConfig(Section):
    """The depth camera: an Asus Xtion Pro Live rendered at ``width`` x ``height``."""

    width: int = Field(160, ge=8, le=4096)
    height: int = Field(120, ge=8, le=4096)


class NoiseConfig(Section):
    """Xtion sensor noise (Nguyen et al. 2012); off by default, as in the paper's simulation."""

    enabled: bool = False
    axial: bool = True
    quantisation: bool = True
    missing: bool = True
    missing_start_deg: float = Field(70.0, ge=0, le=90)
    missing_full_deg: float = Field(85.0, ge=0, le=90)
    baseline_m: float = Field(0.075, gt=0)
    subpixel: int = Field(8, ge=1)

    @model_validator(mode="after")
    def _ordered(self) -> NoiseConfig:
        if self.missing_full_deg < self.missing_start_deg:
            raise ValueError("missing_full_deg must not be below missing_start_deg")
        return self


class RenderConfig(Section):
    """The training viewsphere: near-uniform views over the whole sphere."""

    views: int = Field(60, ge=1, description="views per model (the training images: train "
                       "models x views; 60 keeps the demo's training under 5 min on 2 cores)")
    radius_m: float = Field(0.6, gt=0)
    noise: NoiseConfig = NoiseConfig()


class ViewpointsConfig(Section):
    """The test viewpoints X_rho: near-uniform on the upper hemisphere."""

    count: int = Field(128, ge=2)
    radius_m: float = Field(0.6, gt=0)


class PreprocessConfig(Section):
    """The classifier's input: crop, depth normalisation, size (see recognition.preprocess)."""

    input_size_px: int = Field(64, ge=32, le=512)
    crop_size_m: float = Field(0.5, gt=0, description="crop side at the object's distance")
    depth_range_m: float = Field(0.2, gt=0, description="depth offset mapped to +-1")
    background: float = -1.0
    fit_margin: float = Field(0.05, ge=0, description="room around an object wider than the crop")


class AugmentConfig(Section):
    """Training augmentation: random crop shifts and scales, optional Xtion depth noise."""

    shift: float = Field(0.05, ge=0, le=0.5, description="max crop shift, fraction of its side")
    scale: float = Field(0.1, ge=0, lt=1, description="max relative change of the crop size")
    noise: bool = Field(False, description="add axial + quantisation noise (render.noise model)")


class TrainConfig(Section):
    """The depth classifier and its training (paper Sec. 5.1.1: Adam, weight decay 5e-4, batch
    128; its lr 1e-4 fine-tuned a pretrained network, from scratch 1e-3 measured far better)."""

    width: float = Field(0.25, gt=0, le=4, description="channel multiplier of AlexNet's widths")
    dropout: float = Field(0.5, ge=0, lt=1)
    epochs: int = Field(25, ge=1)
    batch_size: int = Field(128, ge=1)
    learning_rate: float = Field(
        1e-3, gt=0, description="Adam's; chosen on validation accuracy (docs/recognition.md)")
    weight_decay: float = Field(5e-4, ge=0)
    validation_fraction: float = Field(
        0.1, ge=0, lt=1, description="training views held out per model for validation"
    )
    device: Literal["auto", "cpu", "cuda"] = "auto"
    preprocess: PreprocessConfig = PreprocessConfig()
    augment: AugmentConfig = AugmentConfig()


class SaliencyConfig(Section):
    """2D saliency maps of each class's volume model (paper Sec. 4.2; see docs/awareness.md).

    ``mask`` is Fong & Vedaldi's meaningful perturbation; its sizes default to their 224 px
    values scaled to the classifier's input (None = scaled).
    """

    method: Literal["mask", "gradient", "smoothgrad", "gradcam", "integrated_gradients",
                    "occlusion"] = "mask"
    iterations: int = Field(
        50, ge=1, description="mask: Adam steps (reference 300; 50 measured r = 0.989 to it)")
    learning_rate: float = Field(0.1, gt=0, description="mask: Adam learning rate")
    l1: float = Field(1e-2, ge=0, description="mask: weight of mean(1 - m)")
    tv: float = Field(1e-4, ge=0, description="mask: weight of the mean TV_beta")
    tv_beta: float = Field(3.0, gt=0)
    mask_initial: float = Field(0.5, ge=0, le=1, description="mask: starting value")
    mask_size_px: int | None = Field(None, ge=2, description="mask side (None: 28 * S / 224)")
    blur_sigma_px: float | None = Field(None, ge=0, description="None: 10 * S / 224")
    jitter_px: int | None = Field(None, ge=0, description="None: 4 * S / 224")
    smoothgrad_samples: int = Field(16, ge=1)
    smoothgrad_sigma: float = Field(0.15, gt=0, description="noise std in input units")
    ig_steps: int = Field(32, ge=2)
    occlusion_window_px: int | None = Field(None, ge=1, description="None: S / 8")
    batch_size: int = Field(128, ge=1, description="views attributed together")


class VolumeConfig(Section):
    """The 3D dense saliency volume: voxels along the object's longest side (paper: 25-80)."""

    resolution: int = Field(40, ge=2, le=256)


class ObserveConfig(Section):
    """Observation models P(o | class, viewpoint) (see docs/awareness.md)."""

    calibration: Literal["logistic", "isotonic"] = "logistic"
    classifier_pseudo_count: float = Field(
        0.1, gt=0, description="Classifier model: pseudo-count per (viewpoint, class, label)")
    confusion_pseudo_count: float = Field(
        1.0, ge=0, description="RA / black-box: pseudo-count per (class, label) of the confusion")
    evidence: Literal["volume", "crossfit", "both"] = Field(
        "both", description="held-out evidence the models are fitted on: the volume models "
        "under the classifier (the paper's), cross-fitted training models, or both")
    crossfit_folds: int = Field(3, ge=2, description="cross-fitting folds over training models")
    crossfit_epochs: int = Field(
        6, ge=1, description="epochs of each fold's classifier (the demo's time budget)")
    contrastive: bool = Field(
        False, description="also fit ra_contrastive: each class's saliency volume against its "
        "most confused class (one more mask per volume-model view)")
    ra_model: Literal["auto", "paper", "class", "area", "class_area", "contrastive",
                      "viewpoint"] = Field(
        "auto", description="the recognition-aware model RA-POMDP uses ('ra'); auto: the "
        "variant with the best held-out log-likelihood (leave-one-group-out over the evidence)")
    belief_correction: Literal["none", "temperature"] = Field(
        "temperature", description="temperature: every model's likelihoods raised to a power "
        "fitted on held-out multi-view episodes (correlated views count less than independent)")


class VPTreeConfig(Section):
    """The VP-tree baseline (Atanasov et al. 2014): a vocabulary tree over local depth patches
    and its per-viewpoint confusion (see docs/recognition.md, "VP-tree baseline")."""

    branching: int = Field(10, ge=2, le=64, description="children per tree node (k-means k)")
    levels: int = Field(3, ge=1, le=6, description="tree depth; branching**levels leaves")
    patch_size_m: float = Field(
        0.08, gt=0, description="side of a descriptor's patch on the surface, in metres")
    patch_samples: int = Field(5, ge=2, le=15, description="depth samples per patch side")
    stride_px: int = Field(4, ge=1, description="keypoint grid spacing in image pixels")
    max_fit_descriptors: int = Field(
        100_000, ge=100, description="descriptors (random subsample) the k-means are fitted on")
    top_k: int = Field(
        1, ge=1, description="best-matching training views voting (1: the best match's class)")
    pseudo_count: float = Field(
        0.1, gt=0, description="pseudo-count per (viewpoint, class, label) of the confusion")


class SolveConfig(Section):
    """The active-recognition POMDP built from the workspace, and its solver."""

    wrong_declaration_cost_m: float = Field(
        2.0, gt=0, description="lambda (Eq. 1): a wrong declaration's cost, in metres of E_M")
    discount: float = Field(0.95, gt=0, lt=1)
    precision: float = Field(1e-3, gt=0, description="stop when upper - lower is below this")
    iterations: int | None = Field(
        25, ge=1, description="solver iterations per observation model: the budget that makes "
        "a run reproducible (None: until precision or timeout_s)")
    timeout_s: float = Field(
        120.0, gt=0, description="CPU seconds per observation model at most; a solve stopped "
        "by it depends on the machine's speed (solve_summary.json: timed_out)")
    models: list[str] | None = Field(
        ["ra", "classifier", "vptree"],
        description="observation models to solve (the closed-loop evaluation's three); others: "
        "ra_class, blackbox; null: every model the observe and vptree stages made")


class Config(Section):
    """Everything a run needs; ``Config()`` is the embedded default."""

    seed: int = 0
    dataset: DatasetConfig = DatasetConfig()
    camera: CameraConfig = CameraConfig()
    render: RenderConfig = RenderConfig()
    viewpoints: ViewpointsConfig = ViewpointsConfig()
    train: TrainConfig = TrainConfig()
    saliency: SaliencyConfig = SaliencyConfig()
    volume: VolumeConfig = VolumeConfig()
    observe: ObserveConfig = ObserveConfig()
    robot: RobotConfig = RobotConfig()
    vptree: VPTreeConfig = VPTreeConfig()
    solve: SolveConfig = SolveConfig()
    evaluate: EvaluateConfig = EvaluateConfig()

    def section(self, name: str) -> Any:
        """A section's values as plain JSON-able data (for hashing and records)."""
        value = getattr(self, name)
        return value.model_dump(mode="json") if isinstance(value, BaseModel) else value

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)


def _describe(error: dict[str, Any]) -> str:
    where = ".".join(str(part) for part in error["loc"]) or "(top level)"
    if error["type"] == "extra_forbidden":
        return f"{where}: unknown key"
    got = error.get("input")
    shown = "" if isinstance(got, dict) else f" (got {got!r})"
    return f"{where}: {error['msg']}{shown}"


def config_from_dict(data: dict[str, Any], source: str = "configuration") -> Config:
    """Validate a mapping; errors name every wrong key or value."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping of sections, got {type(data).__name__}")
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        lines = "\n".join(f"  {_describe(e)}" for e in exc.errors())
        raise ConfigError(f"{source}: invalid configuration\n{lines}") from None


def load_config(path: str | Path | None) -> Config:
    """Read a YAML configuration; ``None`` gives the default."""
    if path is None:
        return Config()
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path}: not valid YAML ({exc})") from None
    return config_from_dict({} if data is None else data, str(path))
