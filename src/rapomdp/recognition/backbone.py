"""The pretrained depth backbone: the convolutions a classifier starts from, and their card.

A backbone is two files side by side: ``<name>.pt``, the state dict of a
:class:`~rapomdp.recognition.network.DepthAlexNet`'s ``features`` (written with ``torch.save``,
read with ``weights_only=True``), and ``<name>.json``, its model card: the format, the network
spec and preprocessing it was trained for, the SHA-256 of the weights, the corpus, the recipe,
the seconds and the transfer measured (docs/recognition.md). The package ships one,
:data:`SHIPPED_BACKBONE`, made by ``rapomdp pretrain`` (:mod:`rapomdp.pretrain`); the train
stage starts from it with ``train.backbone: pretrained``, or from any file this module wrote
(``train.backbone: path/to/backbone.pt``).

A file whose weights do not match the card's SHA-256, or that is not a backbone, is refused
with :class:`BackboneError` naming the file: a backbone is loaded only after its hash is checked.

Example:
    >>> from rapomdp.recognition.backbone import SHIPPED_BACKBONE, load_backbone
    >>> backbone = load_backbone(SHIPPED_BACKBONE)
    >>> backbone.card["format"], backbone.spec.input_size_px
    ('rapomdp-depth-backbone/1', 64)
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch

from rapomdp.io import ArtefactError, read_json, write_bytes_atomic, write_json_atomic
from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
from rapomdp.recognition.preprocess import PreprocessParams

BACKBONE_FORMAT = "rapomdp-depth-backbone/1"
#: The backbone the package ships (its card beside it, ``.json``).
SHIPPED_BACKBONE = Path(__file__).parent / "weights" / "depth-backbone-v1.pt"
#: Fine-tuning's learning rate of the pretrained convolutions, as a fraction of
#: ``train.learning_rate`` (the new linear layer's): the paper fine-tuned its pretrained
#: network at 1e-4 (Sec. 5.1.1), a tenth of the rate the from-scratch network trains at.
BACKBONE_LR_FACTOR = 0.1


class BackboneError(ArtefactError):
    """A backbone is missing, tampered with, or does not fit the network asked for."""


@dataclass(frozen=True)
class Backbone:
    """A loaded backbone.

    Attributes:
        path: its weights file.
        state: the ``features.*`` tensors of a DepthAlexNet.
        spec: the network it was trained in (its ``classes`` are the corpus's).
        preprocessing: the input it was trained on.
        card: the model card (``<name>.json``).
    """

    path: Path
    state: dict[str, torch.Tensor]
    spec: NetworkSpec
    preprocessing: PreprocessParams
    card: dict[str, Any]

    @property
    def sha256(self) -> str:
        """The weights' SHA-256 (checked when loaded)."""
        return str(self.card["weights_sha256"])


def card_path(path: Path) -> Path:
    """The card beside a backbone's weights."""
    return path.with_suffix(".json")


def write_backbone(path: Path, state: dict[str, torch.Tensor], spec: NetworkSpec,
                   preprocessing: PreprocessParams, card: dict[str, Any]) -> Path:
    """Write a backbone's weights and card atomically.

    Args:
        path: the weights file (``.pt``).
        state: the ``features.*`` tensors.
        spec: the network they were trained in.
        preprocessing: the input they were trained on.
        card: what else the card records (corpus, recipe, seconds, transfer).

    Returns:
        ``path``.
    """
    if not state or not all(key.startswith("features.") for key in state):
        raise ValueError("a backbone's state holds the features.* tensors, and only those")
    buffer = io.BytesIO()
    torch.save({k: v.detach().cpu().contiguous() for k, v in state.items()}, buffer)
    data = buffer.getvalue()
    write_bytes_atomic(path, data)
    write_json_atomic(card_path(path), {"format": BACKBONE_FORMAT, "network": spec.to_dict(),
                                        "preprocessing": preprocessing.to_dict(),
                                        "weights_sha256": hashlib.sha256(data).hexdigest(),
                                        "weights_bytes": len(data), **card})
    return path


def load_backbone(path: str | Path) -> Backbone:
    """Read a backbone after checking its weights against the card's SHA-256.

    Args:
        path: the weights file (or its card).

    Returns:
        The backbone.

    Raises:
        BackboneError: no such file, not a backbone, or weights that do not match the card.
    """
    path = Path(path)
    weights = path.with_suffix(".pt")
    card_file = card_path(weights)
    if not weights.is_file() or not card_file.is_file():
        raise BackboneError(f"{weights}: no backbone here (it needs {weights.name} and "
                            f"{card_file.name} side by side; make one with rapomdp pretrain)")
    card = read_json(card_file)
    if not isinstance(card, dict) or card.get("format") != BACKBONE_FORMAT:
        raise BackboneError(f"{card_file}: not a rapomdp depth backbone card")
    data = weights.read_bytes()
    if hashlib.sha256(data).hexdigest() != card.get("weights_sha256"):
        raise BackboneError(f"{weights}: the weights do not match the SHA-256 in "
                            f"{card_file.name} (tampered with, or a partial copy); refused")
    try:
        state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
        spec = NetworkSpec.from_dict(card["network"])
        preprocessing = PreprocessParams(**card["preprocessing"])
    except Exception as exc:  # an unreadable file is a bad backbone, named
        raise BackboneError(f"{weights}: cannot read the backbone ({exc})") from exc
    return Backbone(weights, state, spec, preprocessing, card)


def check_fits(backbone: Backbone, spec: NetworkSpec, preprocessing: PreprocessParams) -> None:
    """Refuse a backbone that was trained for another network or input.

    Args:
        backbone: the backbone.
        spec: the network the train stage builds.
        preprocessing: its input.

    Raises:
        BackboneError: naming the setting that differs and how to match it.
    """
    checks = [("train.width", backbone.spec.width, spec.width),
              ("train.preprocess.input_size_px", backbone.spec.input_size_px,
               spec.input_size_px),
              ("train.preprocess (the normals' scale)", backbone.spec.normal_scale,
               spec.normal_scale),
              ("train.preprocess.background", backbone.spec.input_background,
               spec.input_background),
              ("train.preprocess.depth_range_m", backbone.preprocessing.depth_range_m,
               preprocessing.depth_range_m),
              ("train.preprocess.crop_size_m", backbone.preprocessing.crop_size_m,
               preprocessing.crop_size_m)]
    for key, trained, asked in checks:
        if abs(float(trained) - float(asked)) > 1e-9 * max(1.0, abs(float(trained))):
            raise BackboneError(
                f"{backbone.path}: the backbone was pretrained with {key} {trained}, this "
                f"configuration asks {asked}; set {key}: {trained}, or train.backbone: "
                "scratch")


def initialise_from_backbone(network: DepthAlexNet, backbone: Backbone) -> None:
    """Copy the backbone's convolutions into ``network`` (its linear layer is left as drawn).

    Args:
        network: a DepthAlexNet of a spec :func:`check_fits` accepted.
        backbone: the backbone.
    """
    network.features.load_state_dict(
        {k.removeprefix("features."): v for k, v in backbone.state.items()}, strict=True)
