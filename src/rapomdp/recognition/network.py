"""DepthAlexNet: AlexNet's five convolutions on depth and its normals, then one linear layer.

As in the paper (Sec. 5.1.1), AlexNet's three fully connected layers are replaced by a single
linear layer from the flattened convolutional features to the classes. Two things differ from the
ImageNet network, because no pretrained weights can be used here and the input is small:

* ``width`` scales every convolution's channel count (AlexNet's 64, 192, 384, 256, 256 at 1.0);
* for inputs under 128 px the first layer is a 5x5 stride-2 convolution instead of 11x11
  stride 4, so a 64 px input keeps a 3x3 feature map after the third pooling (AlexNet: 6x6 from
  224 px).

Dropout before the linear layer stands in for the dropout of the removed layers. A fixed first
layer (:class:`SurfaceNormals`) appends the unit surface normal computed from the depth input,
so the convolutions see local shape explicitly (chosen on held-out objects:
docs/decisions/0019-surface-normals.md); the network's input stays the one depth channel, so
preprocessing and saliency see one channel.

:class:`DepthEnsemble` averages the class probabilities of ``members`` such networks, each
trained from its own seed (``train.ensemble``): the mean of independently trained networks is
more accurate and better calibrated on unseen objects than any one of them (docs/recognition.md).
:func:`build_network` builds the one a :class:`NetworkSpec` describes, or a user's own
recogniser (``train.network``, a :class:`~rapomdp.recognition.custom.CustomSpec`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, replace
from typing import Any

import torch
from torch import nn

from rapomdp.recognition.custom import CUSTOM_KIND, CustomNetwork, CustomSpec

ALEXNET_CHANNELS = (64, 192, 384, 256, 256)
#: What the first convolution sees, as a checkpoint records it: the depth and its normals.
INPUT_FEATURES = "depth_normals"


def _pair(value: int | tuple[int, ...]) -> tuple[int, int]:
    return (value, value) if isinstance(value, int) else (int(value[0]), int(value[1]))


class MaxPool2d(nn.MaxPool2d):
    """``nn.MaxPool2d`` whose forward without autograd is two separable passes of strided
    maxima (over columns, then rows): the same values bit for bit (a maximum is exact), about
    five times faster on this network's NCHW activations than PyTorch's CPU pooling. With
    autograd (training, saliency) it is PyTorch's own, whose indices the backward needs."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        plain = (self.padding in (0, (0, 0)) and self.dilation in (1, (1, 1))
                 and not self.ceil_mode and not self.return_indices and x.dim() == 4)
        if not plain or (torch.is_grad_enabled() and x.requires_grad):
            return super().forward(x)
        (kh, kw), (sh, sw) = (_pair(v) for v in (self.kernel_size, self.stride or self.kernel_size))
        oh, ow = (x.shape[2] - kh) // sh + 1, (x.shape[3] - kw) // sw + 1
        cols = x[..., : sw * (ow - 1) + 1 : sw]
        for j in range(1, kw):
            cols = torch.maximum(cols, x[..., j : j + sw * (ow - 1) + 1 : sw])
        out = cols[:, :, : sh * (oh - 1) + 1 : sh]
        for i in range(1, kh):
            out = torch.maximum(out, cols[:, :, i : i + sh * (oh - 1) + 1 : sh])
        return out


class SurfaceNormals(nn.Module):
    """(n, 1, S, S) preprocessed depth -> (n, 4, S, S): the depth and its unit surface normal.

    The input is ``(reference - depth) / depth_range_m`` per pixel (near positive), so with
    ``scale`` = depth_range_m / (the input pixel's side in metres) the normal of the surface
    is ∝ (−scale·∂v/∂u, −scale·∂v/∂v, 1), by central differences. Its three channels are 0
    where the pixel or one of its four neighbours is ``background`` (the silhouette, where a
    difference would measure the jump to the background, not the surface). Not learned.
    """

    def __init__(self, scale: float, background: float) -> None:
        super().__init__()
        if not scale > 0:
            raise ValueError(f"the normals' scale must be positive, got {scale}")
        self.scale = float(scale)
        self.background = float(background)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        padded = nn.functional.pad(x, (1, 1, 1, 1), value=self.background)
        du = (padded[..., 1:-1, 2:] - padded[..., 1:-1, :-2]) * (0.5 * self.scale)
        dv = (padded[..., 2:, 1:-1] - padded[..., :-2, 1:-1]) * (0.5 * self.scale)
        inverse_length = torch.rsqrt(1.0 + du * du + dv * dv)
        empty = padded <= self.background + 1e-6
        surface = ~(empty[..., 1:-1, 1:-1] | empty[..., 1:-1, 2:] | empty[..., 1:-1, :-2]
                    | empty[..., 2:, 1:-1] | empty[..., :-2, 1:-1])
        weight = inverse_length * surface
        return torch.cat([x, -du * weight, -dv * weight, weight], dim=1)


@dataclass(frozen=True)
class NetworkSpec:
    """Everything needed to rebuild the network; stored in the checkpoint.

    Attributes:
        classes: outputs of the last layer.
        input_size_px: side S of the (1, S, S) depth input, pixels.
        width: multiplier of AlexNet's channel counts.
        dropout: probability of the dropout before the linear layer.
        members: networks of the ensemble (1: one network).
        normal_scale: :class:`SurfaceNormals`'s ``scale``, depth_range_m over the input
            pixel's side in metres.
        input_background: the input's background value (:class:`SurfaceNormals`'s).
    """

    classes: int
    input_size_px: int = 64
    width: float = 0.25
    dropout: float = 0.5
    members: int = 1
    normal_scale: float = 1.0
    input_background: float = -1.0

    def to_dict(self) -> dict[str, float | int | str]:
        """The checkpoint's record: the fields, and ``input_features`` (what the first
        convolution sees), as every checkpoint since the normals were added records them."""
        fields: dict[str, float | int | str] = asdict(self)
        scale, background = fields.pop("normal_scale"), fields.pop("input_background")
        return {**fields, "input_features": INPUT_FEATURES, "normal_scale": scale,
                "input_background": background}

    @classmethod
    def from_dict(cls, record: Mapping[str, Any]) -> NetworkSpec:
        """The spec a checkpoint's record (:meth:`to_dict`) describes.

        Args:
            record: the ``network`` entry of a checkpoint's ``classifier.json``.

        Returns:
            The spec.

        Raises:
            ValueError: the record is of a network this version no longer builds (depth
                alone, or batch normalisation), or has a field the spec lacks.
        """
        fields = dict(record)
        features = fields.pop("input_features", "depth")
        norm = fields.pop("norm", "none")
        if features != INPUT_FEATURES or norm != "none":
            raise ValueError(
                f"a network of input_features {features!r} and norm {norm!r} is no longer "
                f"built (only {INPUT_FEATURES!r} without normalisation: "
                "docs/decisions/0019-surface-normals.md, 0013-batch-norm.md); retrain it")
        return cls(**fields)

    @property
    def input_channels(self) -> int:
        """Channels the first convolution sees: the depth, and the normal's three."""
        return 4

    @property
    def channels(self) -> tuple[int, ...]:
        return tuple(max(4, round(c * self.width)) for c in ALEXNET_CHANNELS)


class DepthAlexNet(nn.Module):
    """(n, 1, S, S) depth inputs -> (n, classes) logits."""

    def __init__(self, spec: NetworkSpec) -> None:
        super().__init__()
        if spec.input_size_px < 32:
            raise ValueError(f"input_size_px must be at least 32, got {spec.input_size_px}")
        self.spec = spec
        c1, c2, c3, c4, c5 = spec.channels
        inputs = spec.input_channels
        first = (
            nn.Conv2d(inputs, c1, kernel_size=11, stride=4, padding=2)
            if spec.input_size_px >= 128
            else nn.Conv2d(inputs, c1, kernel_size=5, stride=2, padding=2)
        )
        self.input_layer = SurfaceNormals(spec.normal_scale, spec.input_background)

        def conv_block(conv: nn.Conv2d) -> list[nn.Module]:
            return [conv, nn.ReLU(inplace=True)]

        self.features = nn.Sequential(
            *conv_block(first),
            MaxPool2d(kernel_size=3, stride=2),
            *conv_block(nn.Conv2d(c1, c2, kernel_size=5, padding=2)),
            MaxPool2d(kernel_size=3, stride=2),
            *conv_block(nn.Conv2d(c2, c3, kernel_size=3, padding=1)),
            *conv_block(nn.Conv2d(c3, c4, kernel_size=3, padding=1)),
            *conv_block(nn.Conv2d(c4, c5, kernel_size=3, padding=1)),
            MaxPool2d(kernel_size=3, stride=2),
        )
        with torch.no_grad():
            probe = torch.zeros(1, inputs, spec.input_size_px, spec.input_size_px)
            self.feature_shape = tuple(self.features(probe).shape[1:])
        features = self.feature_shape[0] * self.feature_shape[1] * self.feature_shape[2]
        self.classifier = nn.Sequential(
            nn.Dropout(spec.dropout), nn.Linear(features, spec.classes)
        )

    @property
    def last_conv(self) -> nn.Conv2d:
        """The last convolution (the layer Grad-CAM attributes to)."""
        return [m for m in self.features if isinstance(m, nn.Conv2d)][-1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.classifier(torch.flatten(self.features(self.input_layer(x)), 1))


#: What describes a classifier's network: a DepthAlexNet's spec, or a custom recogniser's.
AnySpec = NetworkSpec | CustomSpec
#: One network of a classifier: a DepthAlexNet, or a user's recogniser wrapped.
MemberNetwork = DepthAlexNet | CustomNetwork


def build_member(spec: AnySpec) -> MemberNetwork:
    """One network of ``spec`` (``members`` 1): a DepthAlexNet, or the user's recogniser
    (its factory imported and called now).

    Args:
        spec: the network's description.

    Returns:
        The network, its weights freshly initialised (from PyTorch's generator).

    Raises:
        ValueError: ``spec`` describes an ensemble.
        RecogniserError: a custom recogniser cannot be imported or built.
    """
    if spec.members != 1:
        raise ValueError(f"one network is built at a time, got a spec of {spec.members} "
                         "members (build_network builds an ensemble)")
    return DepthAlexNet(spec) if isinstance(spec, NetworkSpec) else CustomNetwork(spec)


class DepthEnsemble(nn.Module):
    """``members`` networks (DepthAlexNets, or a custom recogniser's) whose output is the log
    of their mean class probability: a softmax of it is the ensemble's probability, so every
    caller of a network (prediction, the saliency masks' score) sees the ensemble as one
    network."""

    def __init__(self, spec: AnySpec) -> None:
        super().__init__()
        if spec.members < 2:
            raise ValueError(f"an ensemble needs at least 2 members, got {spec.members}")
        self.spec = spec
        member = replace(spec, members=1)
        self.members = nn.ModuleList(build_member(member) for _ in range(spec.members))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        log_p = torch.stack([torch.log_softmax(m(x), dim=1) for m in self.members])
        return torch.logsumexp(log_p, dim=0) - torch.log(torch.tensor(float(len(self.members))))


#: A classifier's network: one network, or an ensemble of them.
Network = DepthAlexNet | CustomNetwork | DepthEnsemble


def build_network(spec: AnySpec) -> Network:
    """The network ``spec`` describes: one DepthAlexNet or custom recogniser (a
    :class:`~rapomdp.recognition.custom.CustomSpec`, whose factory is imported and called
    now), or an ensemble of ``members``.

    Args:
        spec: the network's description.

    Returns:
        The network, its weights freshly initialised (from PyTorch's generator).

    Raises:
        ValueError: ``members`` is below 1.
        RecogniserError: a custom recogniser cannot be imported or built
            (:func:`~rapomdp.recognition.custom.build_recogniser`).
    """
    if spec.members < 1:
        raise ValueError(f"members must be at least 1, got {spec.members}")
    return build_member(spec) if spec.members == 1 else DepthEnsemble(spec)


def spec_from_record(record: Mapping[str, Any]) -> AnySpec:
    """The spec of a checkpoint's ``network`` record: a custom recogniser's (``kind:
    custom``) or a DepthAlexNet's (no ``kind``, as every checkpoint before the option).

    Args:
        record: the ``network`` entry of a checkpoint's ``classifier.json``.

    Returns:
        The spec.

    Raises:
        ValueError: the record is of an unknown kind or a network no longer built.
    """
    kind = record.get("kind")
    if kind is None:
        return NetworkSpec.from_dict(record)
    if kind == CUSTOM_KIND:
        return CustomSpec.from_dict(record)
    raise ValueError(f"a network record of kind {kind!r} is unknown (expected none, a "
                     f"DepthAlexNet, or {CUSTOM_KIND!r})")


def member_networks(network: Network) -> list[MemberNetwork]:
    """The networks whose mean a classifier's network is: an ensemble's members, or itself."""
    if isinstance(network, DepthEnsemble):
        return [member for member in network.members
                if isinstance(member, DepthAlexNet | CustomNetwork)]
    return [network]
