"""Multi-view training of the depth classifier (paper Sec. 5.1.1).

The training set is every training-viewsphere render of the *train* models; a fraction of each
model's views is held out for validation. Every batch is preprocessed on the fly by the one
:func:`~rapomdp.recognition.preprocess.preprocess`, with a random crop shift and scale (and,
optionally, the Xtion's axial and quantisation noise) as augmentation, so no epoch sees the same
input twice. Adam with the paper's learning rate, weight decay and batch size.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import torch
from torch import nn

from rapomdp.config import AugmentConfig, NoiseConfig, PreprocessConfig, TrainConfig
from rapomdp.data.noise import apply_sensor_noise
from rapomdp.data.training_views import TrainingViews
from rapomdp.progress import progress_bar
from rapomdp.recognition.backbone import (
    BACKBONE_LR_FACTOR,
    SHIPPED_BACKBONE,
    Backbone,
    BackboneError,
    check_fits,
    initialise_from_backbone,
    load_backbone,
)
from rapomdp.recognition.classifier import Classifier
from rapomdp.recognition.custom import CustomSpec
from rapomdp.recognition.network import (
    AnySpec,
    DepthAlexNet,
    DepthEnsemble,
    MemberNetwork,
    Network,
    NetworkSpec,
    build_member,
)
from rapomdp.recognition.preprocess import (
    ObjectExtents,
    PreprocessParams,
    object_extents,
    preprocess,
)


@dataclass
class LabelledViews:
    """Depth images (n, H, W) in metres with class labels (n,), model (n,) and view (n,) indices."""

    depth: np.ndarray
    labels: np.ndarray
    models: np.ndarray
    views: np.ndarray

    def subset(self, mask: np.ndarray) -> LabelledViews:
        return LabelledViews(self.depth[mask], self.labels[mask], self.models[mask],
                             self.views[mask])

    def __len__(self) -> int:
        return int(self.labels.shape[0])


@dataclass
class History:
    """Per-epoch training record (of each ensemble member in turn: ``member``)."""

    member: list[int] = field(default_factory=list)
    epoch: list[int] = field(default_factory=list)
    train_loss: list[float] = field(default_factory=list)
    train_accuracy: list[float] = field(default_factory=list)
    val_loss: list[float] = field(default_factory=list)
    val_accuracy: list[float] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    kept: list[int] = field(default_factory=list)  # 1: the epoch whose weights were kept

    def rows(self) -> list[dict[str, float]]:
        keys = ("member", "epoch", "train_loss", "train_accuracy", "val_loss", "val_accuracy",
                "seconds", "kept")
        return [{k: getattr(self, k)[i] for k in keys} for i in range(len(self.epoch))]


def preprocess_params(cfg: PreprocessConfig) -> PreprocessParams:
    return PreprocessParams(**cfg.model_dump())


def collect_views(views: TrainingViews, role: str = "train") -> LabelledViews:
    """Every render of the models with ``role``, labelled by the dataset's class list."""
    depth, labels, models, indices = [], [], [], []
    for i, model in enumerate(views.dataset.with_role(role)):
        d, _ = views.load(model)
        depth.append(d.astype(np.float32))
        labels.append(np.full(d.shape[0], views.dataset.label(model), dtype=np.int64))
        models.append(np.full(d.shape[0], i, dtype=np.int64))
        indices.append(np.arange(d.shape[0]))
    return LabelledViews(np.concatenate(depth), np.concatenate(labels), np.concatenate(models),
                         np.concatenate(indices))


def validation_mask(data: LabelledViews, fraction: float, rng: np.random.Generator) -> np.ndarray:
    """True for the held-out views: ``fraction`` of each model's views, picked at random."""
    held = np.zeros(len(data), dtype=bool)
    if fraction <= 0:
        return held
    # a random key per image, ranked within each model: the lowest ranks are held out
    keys = rng.random(len(data))
    order = np.lexsort((keys, data.models))
    starts = np.searchsorted(data.models[order], data.models[order], side="left")
    rank = np.arange(len(data)) - starts
    counts = np.bincount(data.models)[data.models[order]]
    held[order] = rank < np.round(fraction * counts)
    return held


class BatchAugmentation(NamedTuple):
    """One batch's augmentation: its (noisy) ``depth`` (n, H, W) in metres, crop ``shift``
    (n, 2) in fractions of the crop's side and crop ``scale`` (n,)."""

    depth: np.ndarray
    shift: np.ndarray
    scale: np.ndarray


def augment_batch(
    depth: np.ndarray,
    augment: AugmentConfig,
    noise: NoiseConfig,
    rng: np.random.Generator,
) -> BatchAugmentation:
    """A batch's random augmentation.

    Args:
        depth: (n, H, W) depth images in metres.
        augment: the augmentation's ranges (``train.augment``).
        noise: the sensor noise model added when ``augment.noise`` is on.
        rng: the generator of every draw (noise, then shifts, then scales).

    Returns:
        The batch's depth, crop shifts and crop scales.
    """
    n = depth.shape[0]
    if augment.noise:
        # surface angles are unknown after rendering; 0 keeps axial + quantisation noise only
        depth = apply_sensor_noise(depth, np.zeros_like(depth), noise, rng)
    shift = rng.uniform(-augment.shift, augment.shift, size=(n, 2))
    scale = np.exp(rng.uniform(np.log1p(-augment.scale), np.log1p(augment.scale), size=n))
    return BatchAugmentation(depth, shift, scale)


def augmented_inputs(depth: np.ndarray, augment: AugmentConfig, noise: NoiseConfig,
                     rng: np.random.Generator, fx_px: float, fy_px: float,
                     params: PreprocessParams, extents: ObjectExtents | None = None
                     ) -> np.ndarray:
    """A training batch's network inputs (n, 1, S, S): :func:`augment_batch`'s draw, then the
    one :func:`preprocess`."""
    batch = augment_batch(depth, augment, noise, rng)
    return preprocess(batch.depth, fx_px, fy_px, params, batch.shift, batch.scale,
                      extents).images


def evaluate_inputs(
    network: nn.Module, inputs: np.ndarray, labels: np.ndarray, device: torch.device,
    batch_size: int = 512,
) -> tuple[float, float]:
    """Mean cross-entropy and accuracy of the network on preprocessed inputs."""
    if len(labels) == 0:
        return float("nan"), float("nan")
    network.eval()
    loss, correct = 0.0, 0
    with torch.inference_mode():
        for start in range(0, len(labels), batch_size):
            x = torch.from_numpy(inputs[start : start + batch_size]).to(device)
            y = torch.from_numpy(labels[start : start + batch_size]).to(device)
            logits = network(x)
            loss += float(nn.functional.cross_entropy(logits, y, reduction="sum"))
            correct += int((logits.argmax(1) == y).sum())
    return loss / len(labels), correct / len(labels)


def network_spec(classes: int, cfg: TrainConfig) -> AnySpec:
    """The network a training configuration describes (one member of its ensemble).

    ``train.network`` ``alexnet``: a DepthAlexNet of ``width`` and ``dropout``, whose normals'
    scale is the input's depth unit over its pixel's side at the crop's nominal size
    (docs/recognition.md); an import path: the user's recogniser (a
    :class:`~rapomdp.recognition.custom.CustomSpec`; width and dropout are not read).

    Args:
        classes: logits per image.
        cfg: the ``train`` section.

    Returns:
        The spec of one member.
    """
    pre = cfg.preprocess
    if cfg.network != "alexnet":
        return CustomSpec(cfg.network, classes, pre.input_size_px)
    return NetworkSpec(classes, pre.input_size_px, cfg.width, cfg.dropout,
                       normal_scale=pre.depth_range_m * pre.input_size_px / pre.crop_size_m,
                       input_background=pre.background)


def training_backbone(cfg: TrainConfig) -> Backbone | None:
    """The backbone ``train.backbone`` names, checked against the network the configuration
    builds (None: ``scratch``).

    Args:
        cfg: the training configuration.

    Returns:
        The loaded backbone, or None.

    Raises:
        BackboneError: the file is missing or tampered with, or was pretrained for another
            width or input (the message names the setting).
    """
    if cfg.backbone == "scratch":
        return None
    if cfg.network != "alexnet":
        raise BackboneError(f"train.backbone {cfg.backbone!r} starts the alexnet network's "
                            f"convolutions; train.network is {cfg.network!r}: set "
                            "train.backbone: scratch (a recogniser of your own brings its "
                            "own initial weights)")
    backbone = load_backbone(SHIPPED_BACKBONE if cfg.backbone == "pretrained"
                             else Path(cfg.backbone))
    spec = network_spec(2, cfg)
    assert isinstance(spec, NetworkSpec)  # train.network alexnet, checked above
    check_fits(backbone, spec, preprocess_params(cfg.preprocess))
    return backbone


def optimisation_step(network: nn.Module, optimiser: torch.optim.Optimizer, x: torch.Tensor,
                      y: torch.Tensor) -> tuple[float, int]:
    """One optimiser step of cross-entropy on a batch (the train stage's and pretraining's).

    Args:
        network: the network, in train mode.
        optimiser: its optimiser.
        x: the batch's inputs (n, 1, S, S).
        y: their labels (n,).

    Returns:
        The batch's summed loss (before the step) and how many it classified right.
    """
    logits = network(x)
    loss = nn.functional.cross_entropy(logits, y)
    optimiser.zero_grad(set_to_none=True)
    loss.backward()
    optimiser.step()
    return float(loss.detach()) * len(y), int((logits.argmax(1) == y).sum())


def member_seed(seed: int, member: int) -> int:
    """Ensemble member ``member``'s seed: ``seed`` itself for the first (an ensemble of one is
    the single classifier), then draws of ``SeedSequence([seed, member])`` (so the members of
    the seed-0 and seed-1 classifiers do not share weights)."""
    if member == 0:
        return seed
    return int(np.random.SeedSequence([seed, member]).generate_state(1)[0])


def train_classifier(
    train: LabelledViews,
    val: LabelledViews,
    classes: Sequence[str],
    cfg: TrainConfig,
    fx_px: float,
    fy_px: float,
    seed: int,
    device: torch.device,
    noise: NoiseConfig | None = None,
    progress: bool = True,
    members: Iterable[int] | None = None,
    report: Callable[[int], None] | None = None,
) -> tuple[Classifier, History]:
    """Train ``cfg.ensemble`` networks of ``cfg.network`` (DepthAlexNets, or the user's
    recogniser) on ``train``, each from its own :func:`member_seed`; report ``val`` after
    every epoch (on a progress bar when ``progress``). More than one member gives a
    :class:`DepthEnsemble`.

    ``members`` (indices; None: all) trains a share of the ensemble only (a worker's), and
    ``report(1)`` is called after every batch when given.
    """
    params = preprocess_params(cfg.preprocess)
    spec = network_spec(len(classes), cfg)
    members = list(range(cfg.ensemble) if members is None else members)
    val_inputs = preprocess(val.depth, fx_px, fy_px, params).images if len(val) else None
    # where the object is in each image does not change between epochs (unless the noise
    # augmentation changes the images): found once, the crop alone is redrawn per batch
    extents = None if cfg.augment.noise else object_extents(train.depth)
    noise = noise or NoiseConfig()
    history = History()
    batches = -(-len(train) // cfg.batch_size)
    backbone = training_backbone(cfg)
    networks: list[MemberNetwork] = []
    with progress_bar(progress, status=True) as bar:
        task = bar.add_task("train", total=len(members) * cfg.epochs * batches, status="",
                            unit="batches")
        for member in members:
            name = "train" if cfg.ensemble == 1 else f"train member {member + 1}/{cfg.ensemble}"

            def update(advance: int, text: str | None, status: str, name: str = name) -> None:
                bar.update(task, advance=advance, status=status,
                           description=None if text is None else f"{name} {text}")
                if report is not None and advance:
                    report(advance)

            networks.append(_train_network(
                spec, train, val, val_inputs, extents, cfg, params, fx_px, fy_px,
                member_seed(seed, member), device, noise, history, member, update, backbone))
    return ensemble_classifier(networks, classes, cfg, fx_px, fy_px, device), history


def ensemble_classifier(networks: Sequence[MemberNetwork], classes: Sequence[str],
                        cfg: TrainConfig, fx_px: float, fy_px: float,
                        device: torch.device) -> Classifier:
    """The classifier of trained members: the one network, or their :class:`DepthEnsemble`."""
    params = preprocess_params(cfg.preprocess)
    if len(networks) == 1:
        network: Network = networks[0]
    else:
        network = DepthEnsemble(replace(networks[0].spec, members=len(networks))).to(device)
        for slot, trained in zip(network.members, networks, strict=True):
            slot.load_state_dict(trained.state_dict())
    network.eval()
    return Classifier(network, classes, params, fx_px, fy_px, device)


def merge_histories(histories: Sequence[History]) -> History:
    """One record of several shares of an ensemble's members, in member order."""
    rows = sorted((row for h in histories for row in h.rows()),
                  key=lambda row: (row["member"], row["epoch"]))
    merged = History()
    for row in rows:
        for key, value in row.items():
            getattr(merged, key).append(value)
    return merged


VALIDATION_DROP_NOTE = 0.05
"""A kept epoch that validates this far below the member's best epoch gets a note: on the
study's default seed 1 the last epoch fell 0.30 below its best and its unseen objects 0.18 a
view (docs/recognition.md, "Which epoch a network keeps")."""


def validation_drop_note(history: History) -> str | None:
    """A line for the user when a network's kept epoch validates at least
    ``VALIDATION_DROP_NOTE`` below that network's best epoch, None otherwise."""
    member = np.asarray(history.member)
    accuracy = np.asarray(history.val_accuracy, dtype=np.float64)
    notes = []
    for m in np.unique(member):
        rows = np.flatnonzero(member == m)
        scores = accuracy[rows]
        if not np.isfinite(scores).all():
            continue  # no validation views
        kept = rows[np.asarray(history.kept)[rows] == 1][0]
        best = rows[int(np.argmax(scores))]
        if accuracy[best] - accuracy[kept] >= VALIDATION_DROP_NOTE:
            who = "" if len(np.unique(member)) == 1 else f"member {m + 1}: "
            notes.append(f"{who}the kept epoch {history.epoch[kept]} validates "
                         f"{accuracy[kept]:.3f}, epoch {history.epoch[best]} "
                         f"{accuracy[best]:.3f}")
    if not notes:
        return None
    return ("train: " + "; ".join(notes) + ". A late swing of the learning rate; another seed "
            "(train.seed) keeps a settled network (docs/recognition.md).")


def _train_network(
    spec: AnySpec, train: LabelledViews, val: LabelledViews, val_inputs: np.ndarray | None,
    extents: ObjectExtents | None, cfg: TrainConfig, params: PreprocessParams, fx_px: float,
    fy_px: float, seed: int, device: torch.device, noise: NoiseConfig, history: History,
    member: int, report: Callable[[int, str | None, str], None],
    backbone: Backbone | None = None,
) -> MemberNetwork:
    """One network of ``spec`` (a DepthAlexNet or the user's recogniser, the same loop)
    trained from ``seed``; its epochs are appended to ``history``. With a ``backbone`` (a
    DepthAlexNet only) its convolutions start from the backbone's and learn at
    ``BACKBONE_LR_FACTOR`` times the linear layer's rate (fine-tuning)."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    network = build_member(spec)
    if backbone is None:
        groups = [{"params": list(network.parameters()), "lr": cfg.learning_rate}]
    else:
        assert isinstance(network, DepthAlexNet)  # training_backbone refuses any other
        initialise_from_backbone(network, backbone)
        groups = [{"params": list(network.features.parameters()),
                   "lr": cfg.learning_rate * BACKBONE_LR_FACTOR},
                  {"params": list(network.classifier.parameters()), "lr": cfg.learning_rate}]
    network = network.to(device)
    optimiser = torch.optim.Adam(groups, lr=cfg.learning_rate, weight_decay=cfg.weight_decay)
    batches = -(-len(train) // cfg.batch_size)
    for epoch in range(1, cfg.epochs + 1):
        start_s = time.perf_counter()
        network.train()
        order = rng.permutation(len(train))
        loss_sum, correct = 0.0, 0
        for b in range(batches):
            idx = np.sort(order[b * cfg.batch_size : (b + 1) * cfg.batch_size])
            x = torch.from_numpy(augmented_inputs(
                train.depth[idx], cfg.augment, noise, rng, fx_px, fy_px, params,
                None if extents is None else extents[idx]))
            y = torch.from_numpy(train.labels[idx])
            batch_loss, batch_correct = optimisation_step(network, optimiser, x.to(device),
                                                          y.to(device))
            loss_sum += batch_loss
            correct += batch_correct
            seen = min((b + 1) * cfg.batch_size, len(train))
            report(1, f"{epoch}/{cfg.epochs}",
                   f"loss {loss_sum / seen:.3f} acc {correct / seen:.1%}")
        val_loss, val_acc = (
            evaluate_inputs(network, val_inputs, val.labels, device)
            if val_inputs is not None else (float("nan"), float("nan"))
        )
        history.member.append(member)
        history.epoch.append(epoch)
        history.train_loss.append(loss_sum / len(train))
        history.train_accuracy.append(correct / len(train))
        history.val_loss.append(val_loss)
        history.val_accuracy.append(val_acc)
        history.seconds.append(time.perf_counter() - start_s)
        history.kept.append(int(epoch == cfg.epochs))  # the network keeps its last epoch
        report(0, None, f"loss {loss_sum / len(train):.3f} acc {correct / len(train):.1%} "
               f"val {val_acc:.1%}")
    network.eval()
    return network
