"""DepthAlexNet's pooling: the separable inference path gives PyTorch's values bit for bit."""

from __future__ import annotations

import copy

import pytest
import torch
from torch import nn

from rapomdp.recognition.network import DepthAlexNet, MaxPool2d, NetworkSpec


def activations(shape: tuple[int, ...], seed: int) -> torch.Tensor:
    """ReLU outputs (many ties at 0) with a plateau of equal positive values."""
    generator = torch.Generator().manual_seed(seed)
    x = torch.randn(*shape, generator=generator).relu()
    x[0, 0, :4, :4] = 0.75
    return x


@pytest.mark.parametrize("shape", [(4, 3, 32, 32), (2, 5, 15, 15), (3, 2, 8, 9), (1, 1, 3, 3)])
@pytest.mark.parametrize("kernel, stride", [(3, 2), (2, 2), (3, None), (2, 1)])
def test_inference_pooling_equals_pytorchs_bit_for_bit(shape, kernel, stride) -> None:
    x = activations(shape, seed=sum(shape))
    ours, theirs = MaxPool2d(kernel, stride), nn.MaxPool2d(kernel, stride)
    with torch.inference_mode():
        fast = ours(x)
        assert fast.shape == theirs(x).shape
        assert torch.equal(fast, theirs(x))
    with torch.no_grad():
        assert torch.equal(ours(x), theirs(x))


def test_with_autograd_the_gradient_is_pytorchs() -> None:
    x = activations((3, 4, 15, 15), seed=3)
    grad = torch.randn(3, 4, 7, 7, generator=torch.Generator().manual_seed(4))
    a, b = x.clone().requires_grad_(True), x.clone().requires_grad_(True)
    MaxPool2d(3, 2)(a).backward(grad)
    nn.MaxPool2d(3, 2)(b).backward(grad)
    assert a.grad is not None and b.grad is not None
    assert torch.equal(a.grad, b.grad)


def test_the_network_classifies_as_with_pytorchs_pooling() -> None:
    torch.manual_seed(0)
    network = DepthAlexNet(NetworkSpec(classes=7, input_size_px=64)).eval()
    reference = copy.deepcopy(network)
    for i, layer in enumerate(reference.features):
        if isinstance(layer, MaxPool2d):
            reference.features[i] = nn.MaxPool2d(3, 2)
    assert sum(isinstance(m, MaxPool2d) for m in network.features) == 3
    x = torch.randn(5, 1, 64, 64, generator=torch.Generator().manual_seed(1))
    with torch.inference_mode():
        assert torch.equal(network(x), reference(x))
    # a saliency-style input gradient goes through PyTorch's pooling: the same gradient
    a, b = x.clone().requires_grad_(True), x.clone().requires_grad_(True)
    network(a)[:, 2].sum().backward()
    reference(b)[:, 2].sum().backward()
    assert a.grad is not None and b.grad is not None
    assert torch.equal(a.grad, b.grad)
