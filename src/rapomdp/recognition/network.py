"""DepthAlexNet: AlexNet's five convolutions on one depth channel, then one linear layer.

As in the paper (Sec. 5.1.1), AlexNet's three fully connected layers are replaced by a single
linear layer from the flattened convolutional features to the classes. Two things differ from the
ImageNet network, because no pretrained weights can be used here and the input is small:

* ``width`` scales every convolution's channel count (AlexNet's 64, 192, 384, 256, 256 at 1.0);
* for inputs under 128 px the first layer is a 5x5 stride-2 convolution instead of 11x11
  stride 4, so a 64 px input keeps a 3x3 feature map after the third pooling (AlexNet: 6x6 from
  224 px).

Dropout before the linear layer stands in for the dropout of the removed layers.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import nn

ALEXNET_CHANNELS = (64, 192, 384, 256, 256)


@dataclass(frozen=True)
class NetworkSpec:
    """Everything needed to rebuild the network; stored in the checkpoint."""

    classes: int
    input_size_px: int = 64
    width: float = 0.25
    dropout: float = 0.5

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)

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
        first = (
            nn.Conv2d(1, c1, kernel_size=11, stride=4, padding=2)
            if spec.input_size_px >= 128
            else nn.Conv2d(1, c1, kernel_size=5, stride=2, padding=2)
        )
        self.features = nn.Sequential(
            first,
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(c1, c2, kernel_size=5, padding=2),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(c2, c3, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
            nn.Conv2d(c3, c4, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
            nn.Conv2d(c4, c5, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
        )
        with torch.no_grad():
            probe = torch.zeros(1, 1, spec.input_size_px, spec.input_size_px)
            self.feature_shape = tuple(self.features(probe).shape[1:])
        features = self.feature_shape[0] * self.feature_shape[1] * self.feature_shape[2]
        self.classifier = nn.Sequential(
            nn.Dropout(spec.dropout), nn.Linear(features, spec.classes)
        )

    @property
    def last_conv(self) -> nn.Conv2d:
        """The last convolution (the layer Grad-CAM attributes to)."""
        return self.features[10]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.classifier(torch.flatten(self.features(x), 1))
