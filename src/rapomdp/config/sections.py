"""The configuration's sections: one validated class per stage's settings, a default for every
value, and :class:`Config`, all of them together.

Units: metres and degrees at this surface (``*_m``, ``*_deg``); the code converts to radians.
Each top-level section belongs to the stages that read it, and a stage's cache key hashes only
the sections it reads. Every section is defined here, in a module that imports no stage code, so
that reading a configuration loads no arm, network or solver.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    Discriminator,
    Field,
    Tag,
    field_validator,
    model_validator,
)

from rapomdp.config.files import commented_lines
from rapomdp.io import ArtefactError, check_plain_name
from rapomdp.retired import keyed_retired
from rapomdp.section import Section


class SplitConfig(Section):
    """Fixed models per class for each role, and what becomes of a class's models beyond
    their total (a folder with more): ``train`` adds them to the training models, ``drop``
    leaves them out.

    The default split is ``auto`` (rapomdp.data.splits: every model used, 3 / 1 / 1 at five
    models a class up to 4 / 3 / 4 at eleven); these counts are for a fixed split, e.g. the
    paper's 3 / 1 / 1 in ``configs/paper.yaml``. 4 / 3 / 4: 4 test models a class for paired
    statistics over test models, 3 volume models a class as held-out evidence of the trained
    classifier (the first of them also makes the saliency volume, ``volume.models_per_class``).
    """

    train: int = Field(4, ge=1)
    volume: int = Field(3, ge=1)
    test: int = Field(4, ge=1)
    extra: Literal["train", "drop"] = "train"

    @property
    def total(self) -> int:
        return self.train + self.volume + self.test


def _keyed(value: BaseModel) -> dict[str, Any]:
    """``value``'s JSON data less the fields its (and its nested sections')
    ``hash_omits_default`` names while at their default."""
    data = value.model_dump(mode="json")
    for key in type(value).model_fields:
        nested = getattr(value, key)
        if isinstance(nested, BaseModel):
            data[key] = _keyed(nested)
    if not isinstance(value, Section):
        return data
    for key in value.hash_omits_default:
        if getattr(value, key) == type(value).model_fields[key].default:
            data.pop(key)
    return data


def _split_kind(value: Any) -> str:
    """``dataset.split``'s form: the word ``auto`` or a mapping of counts (a tag in errors'
    locations only, which :func:`_describe` leaves out)."""
    return "<auto>" if isinstance(value, str) else "<counts>"


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
        None, ge=1, description="procedural models per class (default: the split's total; "
        "auto: the size at which it reaches 4 / 3 / 4)"
    )
    radius_m: float = Field(0.2, gt=0, description="bounding-sphere radius after normalisation")
    split: Annotated[
        Annotated[Literal["auto"], Tag("<auto>")] | Annotated[SplitConfig, Tag("<counts>")],
        Discriminator(_split_kind),
    ] = Field("auto", description="auto: every model of a class used, its roles by the "
              "documented rule (docs/conventions.md); or fixed counts {train, volume, test, "
              "extra}")
    too_few_models: Literal["error", "drop"] = Field(
        "error", description="a class with fewer models than the split needs: an error "
        "naming it, or drop: the class left out (one warning line)")

    @field_validator("classes")
    @classmethod
    def _plain_class_names(cls, classes: list[str] | None) -> list[str] | None:
        for name in classes or ():
            try:
                check_plain_name(name, "class", "dataset.classes")
            except ArtefactError as exc:
                raise ValueError(str(exc).removeprefix("dataset.classes: ")) from None
        return classes

    @model_validator(mode="after")
    def _folder_needs_path(self) -> DatasetConfig:
        if self.source == "folder" and self.path is None:
            raise ValueError("source 'folder' needs dataset.path")
        if (isinstance(self.split, SplitConfig) and self.models_per_class is not None
                and self.models_per_class < self.split.total):
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
                       "models x views; the default is the demo's time budget)")
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
    """Training augmentation: random crop shifts and scales and Xtion depth noise."""

    shift: float = Field(0.05, ge=0, le=0.5, description="max crop shift, fraction of its side")
    scale: float = Field(0.1, ge=0, lt=1, description="max relative change of the crop size")
    noise: bool = Field(False, description="add axial + quantisation noise (render.noise model)")


#: ``train.network``'s import path: a dotted module path, a colon, a Python name.
NETWORK_FACTORY = re.compile(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)*:[A-Za-z_]\w*")


def _network_form(value: str) -> str:
    """``train.network`` is ``alexnet`` or an import path (:data:`NETWORK_FACTORY`)."""
    if value != "alexnet" and not NETWORK_FACTORY.fullmatch(value):
        raise ValueError("expected 'alexnet' or an import path 'package.module:factory' (a "
                         "module's dotted path, a colon, the name of a function in it)")
    return value


#: ``train.network``'s type: checked for its form here, imported by the train stage.
NetworkName = Annotated[str, AfterValidator(_network_form)]


class TrainConfig(Section):
    """The depth classifier and its training (paper Sec. 5.1.1: Adam, weight decay 5e-4, batch
    128; its lr 1e-4 fine-tuned a pretrained network, from scratch 1e-3 measured far better).
    The network sees the depth and its surface normals and keeps its last epoch's weights."""

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
    seed: int | None = Field(
        None, ge=0, lt=2**32, description="the classifier's own seed (weights, batch order, "
        "validation split); null: the run's seed. A study varies "
        "it alone with --vary train")
    ensemble: int = Field(
        1, ge=1, le=16, description="networks trained from their own seeds whose mean "
        "probability is the classifier (K times the training, saliency and inference time; "
        "measured more accurate and calibrated on unseen objects: docs/recognition.md)")
    backbone: str = Field(
        "scratch", description="where the convolutions start: scratch (random weights), "
        "pretrained (the backbone shipped with the package, made by rapomdp pretrain: "
        "docs/recognition.md) or the path of a backbone file rapomdp pretrain wrote")
    preprocess: PreprocessConfig = PreprocessConfig()
    augment: AugmentConfig = AugmentConfig()
    network: NetworkName = Field(
        "alexnet", description="the recogniser: alexnet (DepthAlexNet: width, dropout) or "
        "'package.module:factory', factory(classes, input_size_px) -> torch.nn.Module of "
        "logits, imported from your code (docs/recognition.md, Bring your own recogniser)")

    #: At its default, what every workspace before the option trained: out of the keys.
    hash_omits_default: ClassVar[tuple[str, ...]] = ("ensemble", "backbone", "network")

    @field_validator("backbone")
    @classmethod
    def _backbone_form(cls, value: str) -> str:
        if value not in ("scratch", "pretrained") and not value.endswith(".pt"):
            raise ValueError(f"{value!r} is neither scratch, pretrained nor a backbone file "
                             "(.pt, written by rapomdp pretrain)")
        return value


class SaliencyConfig(Section):
    """2D saliency maps of each class's volume model (paper Sec. 4.2; see docs/awareness.md).

    ``mask`` is Fong & Vedaldi's meaningful perturbation; its sizes default to their 224 px
    values scaled to the classifier's input (None = scaled).
    """

    method: Literal["mask", "gradient", "smoothgrad", "gradcam", "integrated_gradients",
                    "occlusion"] = "mask"
    iterations: int = Field(
        50, ge=1, description="mask: Adam steps (against a 300-step reference: "
        "docs/awareness.md, Convergence)")
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
    models_per_class: int | None = Field(
        1, ge=1, description="volume models per class whose saliency maps the volume fuses "
        "(the first ones; null: all). The others are held-out evidence only")


class ObserveConfig(Section):
    """Observation models P(o | class, viewpoint) (see docs/awareness.md)."""

    calibration: Literal["logistic", "isotonic"] = "logistic"
    classifier_pseudo_count: float = Field(
        0.1, gt=0, description="Classifier model: pseudo-count per (viewpoint, class, label)")
    confusion_pseudo_count: float = Field(
        1.0, ge=0, description="RA / black-box: pseudo-count per (class, label) of the confusion")
    ra_model: Literal["paper", "class", "area", "class_area", "viewpoint", "transfer",
                      "mixture"] = Field(
        "mixture", description="the recognition-aware model RA-POMDP uses ('ra'); mixture: "
        "the RA variants averaged with weights fitted on the held-out labels (each group "
        "scored by the variants fitted without it); with too little held-out evidence it falls "
        "back to 'class' and says so (docs/awareness.md 4.4); another name: that variant")


Vector3 = tuple[float, float, float]


class EnergyConfig(Section):
    """Movement energy E_M(x, x') = geodesic length + kappa * penalty(man(q')) [+ joint term].

    The penalty is 0 at the most manipulable reachable viewpoint and grows as man(q') falls
    toward a singularity (man = 0); see docs/robot.md for why this departs from Eq. 3.
    """

    kappa_m: float = Field(0.1, ge=0, description="weight of the singularity penalty, metres")
    penalty: Literal["inverse", "log", "linear"] = Field(
        "inverse",
        description="inverse: m_ref/m - 1; log: -ln(m/m_ref); linear: 1 - m/m_ref "
        "(m_ref = best manipulability over the reachable viewpoints)",
    )
    joint_weight_m_per_rad: float = Field(
        0.0, ge=0, description="weight of the joint-space distance |q' - q| (0 = off)"
    )


class RobotConfig(Section):
    """A Franka Emika Panda (roboticstoolbox's URDF model) with a depth camera on its flange.

    The world frame is the object's: Z up, floor z = 0, the object centred at x = y = 0. The
    test viewpoints lie on the hemisphere of radius ``viewpoints.radius_m`` around ``centroid_m``.
    """

    base_xyz_m: Vector3 = Field(
        (-0.4, 0.0, 0.2),
        description="the arm's base (panda_link0) in the world frame: 0.4 m behind the object, "
        "on a 0.2 m riser",
    )
    base_yaw_deg: float = Field(0.0, description="the base's rotation about world Z")
    centroid_m: Vector3 = Field(
        (0.0, 0.0, 0.2), description="the object's centroid in the world frame (sphere centre)"
    )
    camera_mount_xyz_m: Vector3 = Field(
        (0.0, 0.065, 0.045),
        description="camera centre in the flange (panda_link8) frame",
    )
    camera_mount_rpy_deg: Vector3 = Field(
        (0.0, 0.0, 0.0),
        description="camera frame (optical axis = z) relative to the flange, roll-pitch-yaw",
    )
    roll_samples: int = Field(
        8, ge=1, le=360, description="rolls about the optical axis searched per viewpoint"
    )
    restarts: int = Field(4, ge=1, le=100, description="IK starting configurations per roll")
    iterations: int = Field(40, ge=1, le=1000, description="Levenberg-Marquardt steps per try")
    position_tolerance_m: float = Field(0.001, gt=0, description="FK check: camera position")
    angle_tolerance_deg: float = Field(0.5, gt=0, description="FK check: camera orientation")
    floor_clearance_m: float | None = Field(
        0.05,
        description="the arm's skeleton (segments between link frames, from panda_link1 on) "
        "must stay this high above the floor; null disables the check",
    )
    object_clearance_m: float | None = Field(
        0.25,
        gt=0,
        description="the arm must stay this far from the centroid (object bounding sphere plus "
        "a link radius); null disables the check",
    )
    energy: EnergyConfig = EnergyConfig()


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
        8.0, gt=0, description="lambda (Eq. 1): a wrong declaration's cost, in metres of E_M "
        "(Table 1's; chosen on held-out episodes, docs/experiment.md)")
    discount: float = Field(0.95, gt=0, lt=1)
    precision: float = Field(1e-3, gt=0, description="stop when upper - lower is below this")
    iterations: int | None = Field(
        25, ge=1, description="solver iterations per observation model: the budget that makes "
        "a run reproducible (None: until precision or timeout_s)")
    timeout_s: float = Field(
        120.0, gt=0, allow_inf_nan=False,
        description="process CPU seconds per observation model at most (time asleep or "
        "waiting does not count); a solve stopped by it depends on the machine's speed "
        "(solve_summary.json: timed_out)")
    memory_gb: float = Field(
        4.0, gt=0, allow_inf_nan=False,
        description="memory cap per solve, in GB: every bound's arrays are sized before they "
        "are allocated; the grid upper bound is left out where it does not fit "
        "(solve_summary.json: note)")
    models: list[str] | None = Field(
        ["ra", "classifier", "vptree"],
        description="observation models to solve (the closed-loop evaluation's three); others: "
        "ra_class, blackbox; null: every model the observe and vptree stages made")


#: Display names of the methods (the paper's Table 1 rows, then extra observation models).
METHOD_NAMES = {
    "static": "Static",
    "random": "Random",
    "vptree": "VP-tree",
    "classifier": "Classifier",
    "ra": "RA-POMDP",
    "ra_class": "RA-POMDP (per-class)",
    "blackbox": "Black-box POMDP",
    "learned": "Learned (PPO)",
}


class RandomWalkConfig(Section):
    """The Random method: a walk among the nearest reachable viewpoints, never revisiting."""

    neighbours: int = Field(8, ge=1, description="candidates: the k nearest reachable viewpoints")
    belief_threshold: float = Field(
        0.9, gt=0, le=1, description="stop rule: declare once max belief reaches this")
    max_moves: int = Field(10, ge=0, description="stop rule: declare after this many moves")
    observation_model: str = Field(
        "classifier", description="observation model of its belief update (an observe model)")


class EvaluateConfig(Section):
    """The closed-loop evaluation (paper Sec. 5.2): every test model x start x method.

    The POMDP methods act by a one-step lookahead on their solved value (one backup at the
    belief reached); Random and the POMDP methods report the belief they act on ** a,
    renormalised, a fitted where each method's own held-out closed loop stops (Random's where
    the observe stage's held-out walks stop at its threshold); docs/awareness.md.
    """


    methods: list[str] = Field(
        ["static", "random", "vptree", "classifier", "ra"],
        description="static, random, an observation model solved by the solve stage "
        "(vptree, classifier, ra, ra_class, blackbox), or learned (the learn stage's policy; "
        "configs/learned.yaml)")
    starts_per_model: int = Field(
        4, ge=1, description="start viewpoints per test model, drawn (seeded) among reachable "
        "(the episodes per method: test models x starts)")
    max_moves: int = Field(
        30, ge=0, description="step budget: after this many moves a method must declare")
    revisit: bool = Field(
        False, description="let the POMDP methods move back to a viewpoint they have seen "
        "(the noiseless sensor would show the same image, counted as new evidence)")
    lambdas: list[float] = Field(
        [0.5, 2.0, 8.0], description="accuracy against energy: wrong-declaration costs λ (m) "
        "each POMDP method is also solved and run at (solve.wrong_declaration_cost_m, Table "
        "1's, is always a point); [] for Table 1 alone")
    random_thresholds: list[float] = Field(
        [0.6, 0.9, 0.97], description="accuracy against energy: Random's stop beliefs "
        "(random.belief_threshold, Table 1's, is always a point)")
    random: RandomWalkConfig = RandomWalkConfig()
    figure_class: str = Field("bicycle", description="the class of Fig. 3 and the trajectories "
                              "(the first class when the dataset has no such class)")

    @field_validator("methods")
    @classmethod
    def _known(cls, methods: list[str]) -> list[str]:
        unknown = [m for m in methods if m not in METHOD_NAMES]
        if unknown:
            raise ValueError(f"unknown method(s) {unknown}; methods are: "
                             f"{', '.join(METHOD_NAMES)}")
        if len(set(methods)) != len(methods):
            raise ValueError("a method is listed twice")
        if not methods:
            raise ValueError("list at least one method")
        return methods

    @field_validator("lambdas")
    @classmethod
    def _positive(cls, values: list[float]) -> list[float]:
        if any(v <= 0 for v in values):
            raise ValueError("every λ must be positive (metres of movement energy)")
        return values

    @field_validator("random_thresholds")
    @classmethod
    def _beliefs(cls, values: list[float]) -> list[float]:
        if any(not 0 < v <= 1 for v in values):
            raise ValueError("every stop belief must be in (0, 1]")
        return values


class LearnConfig(Section):
    """The learned baseline ``learned`` (sb3-contrib's MaskablePPO on the recorded evidence of
    the held-out models; see docs/experiment.md); trained only when evaluate.methods lists it.
    The policy chooses a move or to stop, and stopping declares the belief's most likely class
    (as Random and the POMDPs declare)."""


    observation_model: str = Field(
        "ra", description="the observation model of the belief the policy sees (an observe "
        "model; ra: RA-POMDP's)")
    timesteps: int = Field(
        300_000, ge=1, description="environment steps of training per wrong-declaration cost "
        "λ (the training curves show the plateau: docs/experiment.md)")
    envs: int = Field(8, ge=1, description="environments stepped together per rollout")
    rollout_steps: int = Field(256, ge=1, description="steps per environment per update")
    batch_size: int = Field(256, ge=1, description="minibatch of the PPO update")
    epochs: int = Field(4, ge=1, description="passes over each rollout")
    learning_rate: float = Field(
        1e-3, gt=0, description="Adam's; chosen on held-out return (docs/experiment.md, "
        "benchmarks/results/learned_tuning_default.txt)")
    gamma: float = Field(
        1.0, gt=0, le=1, description="discount: 1, the episode's cost as Table 1 scores it "
        "(energy, plus λ for a wrong declaration)")
    gae_lambda: float = Field(0.95, ge=0, le=1)
    entropy_coefficient: float = Field(
        0.0, ge=0, description="the entropy bonus: sb3's default, chosen on held-out return")
    hidden: list[int] = Field([128, 128], min_length=1, description="hidden layer widths of "
                              "the policy and value networks (tanh)")

    @field_validator("hidden")
    @classmethod
    def _widths(cls, widths: list[int]) -> list[int]:
        if any(not 1 <= w <= 4096 for w in widths):
            raise ValueError("every hidden width must be in [1, 4096]")
        return widths


#: A ``dask.distributed`` scheduler's address (``inproc://``: a LocalCluster of this process).
SCHEDULER_PATTERN = r"^(tcp|tls|ws|wss|inproc|ucx)://\S+$"


class ParallelConfig(Section):
    """Where the stages' independent tasks run; in no stage's key (results do not depend on it)."""

    scheduler: str | None = Field(
        None, pattern=SCHEDULER_PATTERN,
        description="a dask.distributed scheduler, e.g. tcp://10.0.0.5:8786 (null: the local "
        "process pool); the workers must see the workspace at the same path")


class LimitsConfig(Section):
    """Bounds on the files read from outside; in no stage's key (they refuse an input, never
    change a result)."""

    mesh_file_mb: float = Field(
        256.0, gt=0, description="the largest mesh file the dataset stage reads (loading takes "
        "about 8x its size in memory); a larger one is refused, named, before it is read")


class Config(Section):
    """Everything a run needs; ``Config()`` is the embedded default."""

    seed: int = Field(0, ge=0, lt=2**32, description="every stage's seed (NumPy, PyTorch)")
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
    learn: LearnConfig = LearnConfig()
    parallel: ParallelConfig = ParallelConfig()
    limits: LimitsConfig = LimitsConfig()

    @model_validator(mode="after")
    def _gradcam_on_one_network(self) -> Config:
        if self.saliency.method == "gradcam" and self.train.ensemble > 1:
            raise ValueError("saliency.method 'gradcam' attributes to one network's last "
                             f"convolution, and train.ensemble {self.train.ensemble} trains "
                             f"{self.train.ensemble} networks: use another method (e.g. "
                             "'mask') or train.ensemble 1")
        return self

    @model_validator(mode="after")
    def _cameras_outside_the_object(self) -> Config:
        for name, radius in (("render.radius_m", self.render.radius_m),
                             ("viewpoints.radius_m", self.viewpoints.radius_m)):
            if radius <= self.dataset.radius_m:
                raise ValueError(f"{name} ({radius}) must exceed dataset.radius_m "
                                 f"({self.dataset.radius_m}): the camera would be inside the "
                                 "object's bounding sphere")
        return self

    @property
    def train_seed(self) -> int:
        """The classifier's seed: ``train.seed``, or the run's seed when that is null."""
        return self.seed if self.train.seed is None else self.train.seed

    def section(self, name: str) -> Any:
        """A section's values as plain JSON-able data (for hashing and records); the fields a
        section's ``hash_omits_default`` names are left out at their default (options added
        after workspaces existed, whose default is what those workspaces did), and the
        retired keys that were in its stage keys are in at their one value
        (:func:`rapomdp.retired.keyed_retired`: the keys of workspaces made before the
        retirement stay)."""
        value = getattr(self, name)
        if not isinstance(value, BaseModel):
            return value
        return {**_keyed(value), **keyed_retired(name)}

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.model_dump(mode="json"), sort_keys=False)

    def to_commented_yaml(self) -> str:
        """The YAML of :meth:`to_yaml` (it loads back to the same configuration) with a short
        comment per section (its docstring's first line) and per key (its Field description
        and the unit its name ends with, e.g. ``_m``: metres)."""
        return "\n".join(commented_lines(self, 0)) + "\n"


