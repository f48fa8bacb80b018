"""Depth CNN classifier: preprocessing, network, training, single-view evaluation."""

from rapomdp.recognition.classifier import (
    CheckpointError,
    CheckpointMismatchError,
    Classifier,
    configure_torch,
    default_threads,
    select_device,
)
from rapomdp.recognition.network import DepthAlexNet, NetworkSpec
from rapomdp.recognition.preprocess import (
    Preprocessed,
    PreprocessParams,
    input_to_image,
    preprocess,
)

__all__ = [
    "CheckpointError",
    "CheckpointMismatchError",
    "Classifier",
    "DepthAlexNet",
    "NetworkSpec",
    "PreprocessParams",
    "Preprocessed",
    "configure_torch",
    "default_threads",
    "input_to_image",
    "preprocess",
    "select_device",
]
