"""DepthAlexNet's pooling: the separable inference path gives PyTorch's values bit for bit; an
ensemble is the mean of its members' probabilities; the surface-normal input layer gives a
known surface's normal."""

from __future__ import annotations

import copy
from dataclasses import replace

import pytest
import torch
from torch import nn

from rapomdp.recognition.network import (
    DepthAlexNet,
    DepthEnsemble,
    MaxPool2d,
    NetworkSpec,
    SurfaceNormals,
    build_network,
    member_networks,
)


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


def ensemble_of_copies(network: DepthAlexNet, members: int) -> DepthEnsemble:
    ensemble = DepthEnsemble(replace(network.spec, members=members)).eval()
    for member in ensemble.members:
        member.load_state_dict(network.state_dict())
    return ensemble


def test_an_ensemble_outputs_the_log_of_its_members_mean_probability() -> None:
    torch.manual_seed(0)
    ensemble = build_network(NetworkSpec(classes=5, input_size_px=32, width=0.125,
                                         members=3)).eval()
    assert isinstance(ensemble, DepthEnsemble) and len(ensemble.members) == 3
    assert all(m.spec.members == 1 for m in ensemble.members)
    x = torch.randn(4, 1, 32, 32, generator=torch.Generator().manual_seed(2))
    with torch.inference_mode():
        members = torch.stack([torch.softmax(m(x), dim=1) for m in ensemble.members])
        out = ensemble(x)
    # distinct members (each its own initialisation), and softmax(out) is their mean
    assert not torch.allclose(members[0], members[1])
    torch.testing.assert_close(torch.softmax(out, dim=1), members.mean(dim=0))
    torch.testing.assert_close(out.exp().sum(dim=1), torch.ones(4))


def test_an_ensemble_of_copies_is_the_network_itself() -> None:
    torch.manual_seed(1)
    network = DepthAlexNet(NetworkSpec(classes=4, input_size_px=32, width=0.125)).eval()
    x = torch.randn(3, 1, 32, 32, generator=torch.Generator().manual_seed(3))
    with torch.inference_mode():
        torch.testing.assert_close(torch.softmax(ensemble_of_copies(network, 2)(x), dim=1),
                                   torch.softmax(network(x), dim=1))


def test_member_networks_are_an_ensembles_members_or_the_network_itself() -> None:
    single = DepthAlexNet(NetworkSpec(classes=3, input_size_px=32, width=0.125))
    ensemble = ensemble_of_copies(single, 3)
    assert member_networks(single) == [single]
    members = member_networks(ensemble)
    assert len(members) == 3 and all(m is e for m, e in zip(members, ensemble.members,
                                                              strict=True))


def test_build_network_refuses_no_members() -> None:
    assert isinstance(build_network(NetworkSpec(classes=3, input_size_px=32)), DepthAlexNet)
    with pytest.raises(ValueError, match="members must be at least 1"):
        build_network(NetworkSpec(classes=3, input_size_px=32, members=0))
    with pytest.raises(ValueError, match="at least 2 members"):
        DepthEnsemble(NetworkSpec(classes=3, input_size_px=32, members=1))


def test_surface_normals_of_a_known_ramp_and_zero_at_the_silhouette() -> None:
    """A ramp v = a·u (near side to the right) has the normal (−k·a, 0, 1) / √(1 + k²a²) inside;
    the normal's channels are 0 on the background and on the pixels next to it; the depth
    channel is the input unchanged."""
    scale, slope = 25.6, 0.01
    x = torch.full((1, 1, 12, 12), -1.0)
    x[0, 0, 2:10, 3:9] = slope * torch.arange(6.0)  # an object of 8 rows × 6 columns
    out = SurfaceNormals(scale, background=-1.0)(x)
    assert out.shape == (1, 4, 12, 12)
    torch.testing.assert_close(out[:, :1], x)
    length = (1.0 + (scale * slope) ** 2) ** 0.5
    inside = out[0, 1:, 3:9, 4:8]  # rows and columns whose four neighbours are the object
    torch.testing.assert_close(inside[0], torch.full((6, 4), -scale * slope / length))
    torch.testing.assert_close(inside[1], torch.zeros(6, 4))
    torch.testing.assert_close(inside[2], torch.full((6, 4), 1.0 / length))
    surface = torch.zeros(12, 12, dtype=torch.bool)
    surface[3:9, 4:8] = True
    assert (out[0, 1:, ~surface] == 0).all()  # background and silhouette
    # a flat surface faces the camera, unit length where defined
    flat = SurfaceNormals(scale, -1.0)(torch.zeros(1, 1, 8, 8))
    torch.testing.assert_close(flat[0, 1:, 1:7, 1:7].norm(dim=0), torch.ones(6, 6))
    torch.testing.assert_close(flat[0, 3, 1:7, 1:7], torch.ones(6, 6))
    with pytest.raises(ValueError, match="the normals' scale must be positive, got 0"):
        SurfaceNormals(0.0, -1.0)


def test_a_normals_network_keeps_one_input_channel_and_its_gradient() -> None:
    """The input stays the depth channel (preprocessing and saliency unchanged); the first
    convolution sees four channels; the input gradient saliency reads exists; the checkpoint's
    record names the input and rebuilds the spec; a record of a retired network is refused."""
    spec = NetworkSpec(classes=3, input_size_px=32, width=0.125, normal_scale=25.6)
    network = DepthAlexNet(spec).eval()
    assert isinstance(network.input_layer, SurfaceNormals)
    assert network.input_layer.scale == 25.6 and network.input_layer.background == -1.0
    first = network.features[0]
    assert isinstance(first, nn.Conv2d) and first.in_channels == 4
    x = torch.full((2, 1, 32, 32), -1.0)
    x[:, :, 8:24, 8:24] = torch.linspace(-0.5, 0.5, 16)
    x.requires_grad_(True)
    network(x)[:, 0].sum().backward()
    assert x.grad is not None and x.grad.abs().sum() > 0
    # the normals layer has no parameters or buffers: the checkpoint holds the convolutions'
    assert all(key.startswith(("features.", "classifier.")) for key in network.state_dict())
    record = spec.to_dict()
    assert record == {"classes": 3, "input_size_px": 32, "width": 0.125, "dropout": 0.5,
                      "members": 1, "input_features": "depth_normals", "normal_scale": 25.6,
                      "input_background": -1.0}
    assert NetworkSpec.from_dict(record) == spec
    for retired in ({**record, "input_features": "depth"}, {**record, "norm": "batch"}):
        with pytest.raises(ValueError, match="is no longer built .*; retrain it"):
            NetworkSpec.from_dict(retired)
    with pytest.raises(TypeError, match="unexpected keyword argument 'colour'"):
        NetworkSpec.from_dict({**record, "colour": 1})
