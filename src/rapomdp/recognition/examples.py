"""Example recognisers for ``train.network`` (docs/recognition.md, Bring your own recogniser).

:func:`small_resnet` is a recogniser of another architecture than DepthAlexNet: a small
residual network (He et al. 2016) with batch normalisation and global average pooling, built
by a factory of the protocol's signature ``factory(classes, input_size_px) -> nn.Module``:

.. code-block:: yaml

    train: {network: "rapomdp.recognition.examples:small_resnet"}

It reads the preprocessed depth input as it is (one channel; no surface normals).

Example:
    >>> import torch
    >>> network = small_resnet(classes=5, input_size_px=32).eval()
    >>> tuple(network(torch.zeros(3, 1, 32, 32)).shape)
    (3, 5)
"""

from __future__ import annotations

import torch
from torch import nn


class ResidualBlock(nn.Module):
    """Two 3x3 convolutions with batch normalisation, added to the input (projected by a 1x1
    convolution when the stride or the channel count changes), then a ReLU."""

    def __init__(self, inputs: int, outputs: int, stride: int = 1) -> None:
        super().__init__()
        self.body = nn.Sequential(
            nn.Conv2d(inputs, outputs, 3, stride=stride, padding=1, bias=False),
            nn.BatchNorm2d(outputs),
            nn.ReLU(inplace=True),
            nn.Conv2d(outputs, outputs, 3, padding=1, bias=False),
            nn.BatchNorm2d(outputs),
        )
        self.shortcut: nn.Module = nn.Identity()
        if stride != 1 or inputs != outputs:
            self.shortcut = nn.Sequential(
                nn.Conv2d(inputs, outputs, 1, stride=stride, bias=False),
                nn.BatchNorm2d(outputs))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.body(x) + self.shortcut(x))


class SmallResNet(nn.Module):
    """(n, 1, S, S) depth -> (n, classes) logits: a stem convolution, one residual block per
    width of ``widths`` (each after the first halving the resolution), global average pooling
    and a linear layer."""

    def __init__(self, classes: int, widths: tuple[int, ...] = (16, 32, 64)) -> None:
        super().__init__()
        if classes < 1 or not widths:
            raise ValueError(f"a SmallResNet needs classes >= 1 and widths, got {classes}, "
                             f"{widths}")
        self.stem = nn.Sequential(
            nn.Conv2d(1, widths[0], 3, stride=2, padding=1, bias=False),
            nn.BatchNorm2d(widths[0]), nn.ReLU(inplace=True))
        blocks = [ResidualBlock(widths[0], widths[0])]
        blocks += [ResidualBlock(a, b, stride=2)
                   for a, b in zip(widths[:-1], widths[1:], strict=True)]
        self.blocks = nn.Sequential(*blocks)
        self.head = nn.Linear(widths[-1], classes)

    @property
    def last_conv(self) -> nn.Module:
        """The last residual block, whose output is the last feature map (Grad-CAM's layer;
        its last ``nn.Conv2d`` in registration order would be the shortcut's projection)."""
        return self.blocks[-1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        features = self.blocks(self.stem(x))
        return self.head(features.mean(dim=(2, 3)))


def small_resnet(classes: int, input_size_px: int) -> nn.Module:
    """A :class:`SmallResNet` for ``classes`` (the ``train.network`` factory protocol).

    Global average pooling makes it work at any input size; inputs under 16 px are refused
    (three halvings would leave under 2 px).

    Args:
        classes: logits per image.
        input_size_px: S, the side of the preprocessed depth input.

    Returns:
        The network, its weights freshly initialised (from PyTorch's generator).
    """
    if input_size_px < 16:
        raise ValueError(f"small_resnet needs inputs of 16 px or more, got {input_size_px}")
    return SmallResNet(classes)
