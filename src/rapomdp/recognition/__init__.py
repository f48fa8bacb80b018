"""Depth CNN classifier: preprocessing, network, training, single-view evaluation.

The names below are loaded on first use (PEP 562), so that importing a light module of this
package (``recognition.artefacts``, ``recognition.evaluation``) does not load PyTorch. The
preprocessing function is ``rapomdp.recognition.preprocess.preprocess`` (the package's
``preprocess`` attribute is its module).
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "CheckpointError": "classifier",
    "CheckpointMismatchError": "classifier",
    "Classifier": "classifier",
    "configure_torch": "classifier",
    "default_threads": "classifier",
    "select_device": "classifier",
    "DepthAlexNet": "network",
    "DepthEnsemble": "network",
    "build_network": "network",
    "NetworkSpec": "network",
    "Preprocessed": "preprocess",
    "PreprocessParams": "preprocess",
    "input_to_image": "preprocess",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
