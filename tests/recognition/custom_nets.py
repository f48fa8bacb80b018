"""Recogniser factories of the ``train.network`` tests, importable as
``tests.recognition.custom_nets:<name>``: one without input gradients, and broken ones."""

from __future__ import annotations

import torch
from torch import nn

#: Not callable: ``train.network`` naming it is refused.
NOT_CALLABLE = 3


class Quantised(nn.Module):
    """A small CNN behind a straight quantisation of its input (``round(8 x) / 8``): its
    weights train (the loss's gradient reaches them) but its input gradient is zero."""

    def __init__(self, classes: int) -> None:
        super().__init__()
        self.features = nn.Sequential(nn.Conv2d(1, 8, 3, stride=2, padding=1), nn.ReLU(),
                                      nn.Conv2d(8, 16, 3, stride=2, padding=1), nn.ReLU())
        self.head = nn.Linear(16, classes)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = torch.round(x * 8) / 8
        return self.head(self.features(x).mean(dim=(2, 3)))


def quantised(classes: int, input_size_px: int) -> nn.Module:
    """A :class:`Quantised` recogniser (no input gradients)."""
    return Quantised(classes)


def linear(classes: int, input_size_px: int) -> nn.Module:
    """A recogniser without a convolution (Grad-CAM has nothing to attribute to)."""
    return nn.Sequential(nn.Flatten(), nn.Linear(input_size_px * input_size_px, classes))


def one_logit_too_many(classes: int, input_size_px: int) -> nn.Module:
    """Logits (n, classes + 1): the wrong shape."""
    return linear(classes + 1, input_size_px)


def not_a_module(classes: int, input_size_px: int) -> object:
    """A function, not an ``nn.Module``."""
    return lambda x: x


def fails(classes: int, input_size_px: int) -> nn.Module:
    """A factory that raises."""
    raise RuntimeError("no weights for this input size")
