"""Bring your own recogniser: any ``torch.nn.Module`` named in the configuration.

``train.network: package.module:factory`` names a function ``factory(classes, input_size_px)``
that returns a module from the preprocessed depth images ``(n, 1, S, S)`` float32 (one
channel: ``(reference - depth) / depth_range_m`` clipped to [-1, 1], background -1, S =
``input_size_px``) to logits ``(n, classes)``. :func:`load_factory` imports it,
:func:`check_recogniser` checks what it returns on a probe batch, and :class:`CustomNetwork`
wraps it so that every caller of a network (training, the checkpoint, saliency, the closed
loop) sees what it sees of a :class:`~rapomdp.recognition.network.DepthAlexNet`: a ``spec``
(:class:`CustomSpec`, what the checkpoint records: the import path, not the code) and a
``last_conv`` for Grad-CAM (the module's own ``last_conv``, else its last ``nn.Conv2d``).

The user's code is imported because the user named it in the configuration (and again when a
checkpoint that names it is loaded); the weights alone are read from the checkpoint, with
``torch.load(..., weights_only=True)``.

Example:
    >>> spec = CustomSpec("rapomdp.recognition.examples:small_resnet", classes=3,
    ...                   input_size_px=32)
    >>> network = CustomNetwork(spec).eval()
    >>> tuple(network(torch.zeros(2, 1, 32, 32)).shape), spec.to_dict()["kind"]
    ((2, 3), 'custom')
    >>> load_factory("rapomdp.recognition.nowhere:net")
    Traceback (most recent call last):
    ...
    rapomdp.recognition.custom.RecogniserError: train.network '...': module ... not found ...
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass
from typing import Any, cast

import torch
from torch import nn

from rapomdp.workspace import StageError

#: The configuration key that names a recogniser's factory (in every error message).
NETWORK_KEY = "train.network"
#: ``kind`` of a custom network's record in a checkpoint (a DepthAlexNet's record has none).
CUSTOM_KIND = "custom"
#: Images of the probe batch a factory's module is checked on.
PROBE_IMAGES = 2

Factory = Callable[[int, int], nn.Module]


class RecogniserError(StageError):
    """A recogniser named by ``train.network`` cannot be imported, built or used; the message
    names the key, the import path and what failed."""


def _fail(path: str, what: str) -> RecogniserError:
    return RecogniserError(f"{NETWORK_KEY} {path!r}: {what}")


def load_factory(path: str) -> Factory:
    """The factory an import path ``package.module:factory`` names, imported now.

    Args:
        path: ``train.network``'s value (not ``alexnet``).

    Returns:
        The callable ``factory(classes, input_size_px) -> torch.nn.Module``.

    Raises:
        RecogniserError: the path is malformed, the module is not found or fails to import,
            it has no such attribute, or the attribute is not callable.
    """
    module_name, colon, attribute = path.partition(":")
    if not colon or not module_name or not attribute:
        raise _fail(path, "expected an import path 'package.module:factory'")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        missing = exc.name or ""
        if missing and (module_name == missing or module_name.startswith(missing + ".")):
            raise _fail(path, f"module {module_name!r} not found ({exc}); is it installed or "
                        "on PYTHONPATH?") from None
        raise _fail(path, f"importing module {module_name!r} failed: {exc}") from exc
    except Exception as exc:  # the user's module raised while it was imported
        raise _fail(path, f"importing module {module_name!r} failed: "
                    f"{type(exc).__name__}: {exc}") from exc
    if not hasattr(module, attribute):
        raise _fail(path, f"module {module_name!r} has no attribute {attribute!r}")
    factory = getattr(module, attribute)
    if not callable(factory):
        raise _fail(path, f"{attribute!r} is a {type(factory).__name__}, not callable: "
                    "expected a function factory(classes, input_size_px) -> torch.nn.Module")
    return cast(Factory, factory)


def probe_batch(input_size_px: int, images: int = PROBE_IMAGES) -> torch.Tensor:
    """A deterministic batch ``(images, 1, S, S)`` spanning the inputs' range [-1, 1] (no
    random draw: building a network after seeding draws the same weights with or without
    the probe)."""
    count = images * input_size_px * input_size_px
    return torch.linspace(-1.0, 1.0, count).reshape(images, 1, input_size_px, input_size_px)


def check_recogniser(network: object, classes: int, input_size_px: int,
                     path: str = "<factory>") -> nn.Module:
    """``network`` if it is a ``torch.nn.Module`` whose output on a probe batch (n, 1, S, S)
    is a tensor of logits (n, classes).

    The probe runs in evaluation mode without gradients (no batch statistic is updated and
    no random number drawn); the module's mode is restored after.

    Args:
        network: what a factory returned.
        classes: the logits the module must give per image.
        input_size_px: S, the side of the preprocessed input.
        path: the import path it came from (named in the errors).

    Returns:
        ``network``, checked.

    Raises:
        RecogniserError: it is not an ``nn.Module``, the probe fails, or its output is not a
            tensor of shape (n, classes).

    Example:
        >>> try:
        ...     check_recogniser(nn.Sequential(nn.Flatten(), nn.Linear(16 * 16, 5)), 4, 16)
        ... except RecogniserError as exc:
        ...     print(exc)
        train.network '<factory>': ... has shape (2, 5); expected logits (2, 4): one per class
    """
    if not isinstance(network, nn.Module):
        raise _fail(path, f"the factory returned a {type(network).__name__}, not a "
                    "torch.nn.Module")
    shape = (PROBE_IMAGES, 1, input_size_px, input_size_px)
    training = network.training
    network.eval()
    try:
        with torch.no_grad():
            first = next(network.parameters(), None)
            device = first.device if first is not None else torch.device("cpu")
            output = network(probe_batch(input_size_px).to(device))
    except Exception as exc:
        raise _fail(path, f"its forward failed on a probe batch {shape} float32: "
                    f"{type(exc).__name__}: {exc}") from exc
    finally:
        network.train(training)
    if not isinstance(output, torch.Tensor):
        raise _fail(path, f"its output on a probe batch {shape} is a {type(output).__name__}; "
                    f"expected a tensor of logits ({PROBE_IMAGES}, {classes})")
    if tuple(output.shape) != (PROBE_IMAGES, classes):
        raise _fail(path, f"its output on a probe batch {shape} has shape "
                    f"{tuple(output.shape)}; expected logits ({PROBE_IMAGES}, {classes}): "
                    "one per class")
    return network


def build_recogniser(path: str, classes: int, input_size_px: int) -> nn.Module:
    """The module ``factory(classes, input_size_px)`` of import path ``path``, checked by
    :func:`check_recogniser`.

    Args:
        path: ``package.module:factory``.
        classes: the logits per image.
        input_size_px: S, the side of the preprocessed input.

    Returns:
        The user's module.

    Raises:
        RecogniserError: as :func:`load_factory` and :func:`check_recogniser`, or the call
            raised.
    """
    factory = load_factory(path)
    try:
        network = factory(classes, input_size_px)
    except Exception as exc:
        raise _fail(path, f"calling it as factory(classes={classes}, "
                    f"input_size_px={input_size_px}) failed: {type(exc).__name__}: {exc}"
                    ) from exc
    return check_recogniser(network, classes, input_size_px, path)


@dataclass(frozen=True)
class CustomSpec:
    """Everything needed to rebuild a custom recogniser; stored in the checkpoint.

    Attributes:
        factory: the import path ``package.module:factory`` (``train.network``).
        classes: logits per image.
        input_size_px: side S of the (1, S, S) depth input, pixels.
        members: networks of the ensemble (1: one network), each the factory's.
    """

    factory: str
    classes: int
    input_size_px: int = 64
    members: int = 1

    def to_dict(self) -> dict[str, str | int]:
        """The checkpoint's record: ``kind: custom`` and the fields."""
        return {"kind": CUSTOM_KIND, **asdict(self)}

    @classmethod
    def from_dict(cls, record: Mapping[str, Any]) -> CustomSpec:
        """The spec a checkpoint's record (:meth:`to_dict`) describes.

        Args:
            record: the ``network`` entry of a checkpoint's ``classifier.json``.

        Returns:
            The spec.

        Raises:
            ValueError: the record is not a custom network's, or has a field the spec lacks.
        """
        fields = dict(record)
        kind = fields.pop("kind", None)
        if kind != CUSTOM_KIND:
            raise ValueError(f"a network record of kind {kind!r} is not a custom recogniser's")
        return cls(**fields)


class CustomNetwork(nn.Module):
    """A user's recogniser (``module``, built by its factory) with what the project's callers
    of a network read: ``spec`` and ``last_conv``. Its state dict is the module's, each key
    prefixed with ``module.``."""

    def __init__(self, spec: CustomSpec) -> None:
        super().__init__()
        if spec.members != 1:
            raise ValueError(f"a CustomNetwork is one network; members {spec.members} is an "
                             "ensemble (recognition.network.build_network)")
        self.spec = spec
        self.module = build_recogniser(spec.factory, spec.classes, spec.input_size_px)

    @property
    def last_conv(self) -> nn.Module:
        """The layer Grad-CAM attributes to: the module's own ``last_conv`` when it has one
        (an ``nn.Module``: a network names its last feature map's layer), else the last
        ``nn.Conv2d`` among its submodules in their registration order.

        Raises:
            RecogniserError: the module names no layer and has no ``nn.Conv2d`` (Grad-CAM
                cannot be used).
        """
        named = getattr(self.module, "last_conv", None)
        if isinstance(named, nn.Module):
            return named
        convolutions = [m for m in self.module.modules() if isinstance(m, nn.Conv2d)]
        if not convolutions:
            raise _fail(self.spec.factory, "saliency.method 'gradcam' needs a convolution to "
                        "attribute to, and this recogniser has no torch.nn.Conv2d and no "
                        "'last_conv' layer; use another saliency.method (e.g. 'mask' or "
                        "'occlusion')")
        return convolutions[-1]

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return cast(torch.Tensor, self.module(x))
