"""Every saliency method puts its mass where a planted classifier looks."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from rapomdp.awareness.saliency import (
    METHODS,
    MaskParams,
    PerturbationMask,
    gaussian_blur,
    input_gradient_problem,
    make_attribution,
    total_variation,
)

SIZE = 64
REGION = (slice(8, 56), slice(8, 48))  # rows, columns the planted classifier reads


class Gate(nn.Module):
    """Rectified high-pass features (+ and - parts), zeroed outside the region: the layer
    Grad-CAM reads. Their sum is |x - mean of its 3x3 neighbourhood| inside the region."""

    def __init__(self) -> None:
        super().__init__()
        self.conv = nn.Conv2d(1, 2, kernel_size=3, padding=1, padding_mode="replicate")
        highpass = -torch.full((3, 3), 1.0 / 9.0)
        highpass[1, 1] += 1.0
        with torch.no_grad():
            self.conv.weight.copy_(torch.stack([highpass, -highpass])[:, None])
            self.conv.bias.zero_()
        region = torch.zeros(1, 1, SIZE, SIZE)
        region[0, 0][REGION] = 1.0
        self.register_buffer("region", region)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.relu(self.conv(x)) * self.region


class Planted(nn.Module):
    """Two classes; logit of class 0 = 20 * (mean high-pass energy in the region - 0.4),
    class 1 = -it. Only the region's pixels matter; blurring the noise there, or setting it to a
    constant, removes the evidence for class 0.
    """

    def __init__(self) -> None:
        super().__init__()
        self.gate = Gate()
        self.last_conv = self.gate

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        features = self.gate(x)
        area = float(self.gate.region.sum())
        s = 20.0 * (features.sum(dim=(1, 2, 3)) / area - 0.4)
        return torch.stack([s, -s], dim=1)


@pytest.fixture(scope="module")
def planted_inputs() -> torch.Tensor:
    generator = torch.Generator().manual_seed(0)
    return torch.randn(3, 1, SIZE, SIZE, generator=generator)


@pytest.fixture(scope="module")
def mask_run(planted_inputs) -> tuple[PerturbationMask, torch.Tensor]:
    """The mask with its default (scaled) hyperparameters, run once for the module."""
    torch.set_num_threads(1)
    mask = PerturbationMask(Planted(), MaskParams.scaled(SIZE))
    return mask, mask.attribute(planted_inputs, torch.zeros(3, dtype=torch.long))


def mass_in_region(maps: torch.Tensor) -> np.ndarray:
    maps = maps.numpy()
    return maps[:, REGION[0], REGION[1]].sum(axis=(1, 2)) / maps.sum(axis=(1, 2))


def test_planted_classifier_is_confident(planted_inputs):
    probs = torch.softmax(Planted()(planted_inputs), dim=1)
    assert torch.all(probs[:, 0] > 0.99)


@pytest.mark.parametrize("method", METHODS)
def test_saliency_mass_falls_in_the_planted_region(method, planted_inputs, mask_run):
    if method == "mask":
        maps = mask_run[1]
    else:
        attribution = make_attribution(method, Planted(), SIZE)
        maps = attribution.attribute(planted_inputs, torch.zeros(3, dtype=torch.long))
    assert maps.shape == (3, SIZE, SIZE)
    assert float(maps.min()) >= 0.0 and float(maps.max()) <= 1.0
    assert np.all(mass_in_region(maps) >= 0.8), mass_in_region(maps)


def test_mask_deletes_the_evidence_and_is_neither_empty_nor_everything(mask_run):
    mask, saliency = mask_run
    assert torch.all(mask.last_probability < 0.5)  # the perturbation drops the class
    deleted = (saliency > 0.5).float().mean(dim=(1, 2))
    region_fraction = 48 * 40 / SIZE**2
    assert torch.all(deleted > 0.05) and torch.all(deleted < 1.2 * region_fraction)


def test_mask_started_at_one_is_stuck_on_a_saturated_softmax(planted_inputs):
    """Why the mask starts at 0.5: from 1 the clean input's saturated softmax gives no gradient."""
    mask = PerturbationMask(Planted(), MaskParams.scaled(SIZE, iterations=30, initial=1.0))
    saliency = mask.attribute(planted_inputs, torch.zeros(3, dtype=torch.long))
    assert float(saliency.max()) < 0.05 and torch.all(mask.last_probability > 0.99)


def test_mask_batch_equals_one_at_a_time(planted_inputs):
    net = Planted()
    params = MaskParams.scaled(SIZE, iterations=20)
    target = torch.zeros(3, dtype=torch.long)
    batch = PerturbationMask(net, params, seed=3).attribute(planted_inputs, target)
    single = torch.cat([PerturbationMask(net, params, seed=3).attribute(planted_inputs[i:i + 1],
                                                                         target[i:i + 1])
                        for i in range(3)])
    assert torch.allclose(batch, single, atol=1e-4)


def test_mask_hyperparameters_scale_with_the_input():
    assert MaskParams.scaled(224).mask_size_px == 28
    assert MaskParams.scaled(224).blur_sigma_px == pytest.approx(10.0)
    small = MaskParams.scaled(64)
    assert small.mask_size_px == 8 and small.jitter_px == 1
    assert small.blur_sigma_px == pytest.approx(10 * 64 / 224)
    assert MaskParams.scaled(64, iterations=7).iterations == 7


def test_blur_keeps_constants_and_tv_of_a_flat_mask_is_zero():
    flat = torch.full((2, 1, 10, 12), 0.3)
    assert torch.allclose(gaussian_blur(flat, 2.0), flat)
    assert torch.all(total_variation(torch.ones(2, 1, 5, 5), 3.0) == 0)


def test_unknown_method_is_named():
    with pytest.raises(ValueError, match="unknown saliency method 'magic'"):
        make_attribution("magic", Planted(), SIZE)


LEFT, RIGHT = (slice(8, 56), slice(4, 30)), (slice(8, 56), slice(34, 60))


class SharedPart(nn.Module):
    """Three classes reading high-pass energy in two regions: class 0 needs both, class 1 (its
    confusable neighbour) only the left one, class 2 neither (a constant logit). Against class 1
    only the right region tells class 0 apart; against everything both regions matter."""

    def __init__(self) -> None:
        super().__init__()
        self.gate = Gate()
        regions = torch.zeros(2, 1, SIZE, SIZE)
        regions[0, 0][LEFT] = 1.0
        regions[1, 0][RIGHT] = 1.0
        self.register_buffer("regions", regions)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        energy = torch.relu(self.gate.conv(x)).sum(dim=1, keepdim=True)  # (n, 1, S, S)
        mean = (energy * self.regions[None, :, 0]).sum(dim=(2, 3)) / self.regions.sum(
            dim=(1, 2, 3))  # (n, 2): left, right
        left, right = 20.0 * (mean[:, 0] - 0.4), 20.0 * (mean[:, 1] - 0.4)
        return torch.stack([left + right, left, torch.full_like(left, 7.0)], dim=1)


def test_the_mask_of_an_ensemble_of_copies_is_the_mask_of_the_network():
    """An ensemble reaches the saliency as one network: of copies, the network's own mask."""
    from dataclasses import replace

    from rapomdp.recognition.network import DepthAlexNet, DepthEnsemble, NetworkSpec

    torch.manual_seed(4)
    network = DepthAlexNet(NetworkSpec(classes=3, input_size_px=32, width=0.125)).eval()
    ensemble = DepthEnsemble(replace(network.spec, members=2)).eval()
    for member in ensemble.members:
        member.load_state_dict(network.state_dict())
    inputs = torch.randn(2, 1, 32, 32, generator=torch.Generator().manual_seed(5))
    target = torch.tensor([0, 2])
    params = MaskParams.scaled(32, iterations=3)  # a mask still moving, not at its bound
    alone = PerturbationMask(network, params, seed=1).attribute(inputs, target)
    together = PerturbationMask(ensemble, params, seed=1).attribute(inputs, target)
    assert float(alone.max()) > 0.1
    torch.testing.assert_close(together, alone, atol=1e-4, rtol=0)


class Detached(nn.Module):
    """Logits of a detached input: autograd has no path back to the input."""

    def __init__(self) -> None:
        super().__init__()
        self.linear = nn.Linear(16, 2)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.linear(x.detach().flatten(1))


class Exploding(nn.Module):
    """Logits whose input gradient is infinite (a square root at 0)."""

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.sqrt(x - x.detach()).flatten(1)[:, :2]


def test_a_network_without_usable_input_gradients_is_told_with_the_reason():
    x = torch.linspace(-1, 1, 3 * 16).reshape(3, 1, 4, 4)
    t = torch.tensor([0, 1, 0])
    assert input_gradient_problem(Detached(), x, t) == (
        "its logits do not depend on the input through autograd")
    assert input_gradient_problem(Exploding(), x, t) == "the gradient is not finite on 3 views"
    assert input_gradient_problem(Planted(), torch.randn(2, 1, SIZE, SIZE),
                                  torch.tensor([0, 1])) is None
    dropout = nn.Sequential(nn.Dropout(0.5), nn.Flatten(), nn.Linear(16, 2)).train()
    assert input_gradient_problem(dropout, x, t) is None and dropout.training  # mode restored
