"""The artefacts of the train, classifier_eval and vptree stages: their names, and the readers
the command line, the report and later stages go through (JSON and NumPy only: no torch).

``W/train/``: the checkpoint (:data:`~rapomdp.recognition.classifier.WEIGHTS_FILE` +
``META_FILE``), :data:`HISTORY_FILE`, :data:`TRAINING_FIGURE`, :data:`METRICS_FILE`.
``W/classifier_eval/``: :data:`METRICS_FILE` (:class:`SingleViewMetrics` over X_rho and the
whole sphere), :data:`PROBABILITIES_FILE`, ``confusion_{xrho,sphere}.csv|png``,
:data:`HEMISPHERE_FIGURE`.
``W/vptree/``: :data:`VPTREE_CLASSIFIER_FILE`, :data:`VPTREE_OBSERVATION_FILE` (``vptree``
(V, C, C) the confusion tempered by the held-out ``temperature``, the model the planner and the
belief use, ``untempered`` the raw confusion, ``classes``), :data:`VPTREE_SUMMARY_FILE`
(:class:`VPTreeSummary`), :data:`VPTREE_OUTPUTS_FILE` (its outputs on the test models at X_rho).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rapomdp.io import ArtefactError, load_npz, read_json

if TYPE_CHECKING:
    from rapomdp.data.dataset import ModelEntry

METRICS_FILE = "metrics.json"
HISTORY_FILE = "history.csv"
TRAINING_FIGURE = "training.png"
PROBABILITIES_FILE = "probabilities.npz"
HEMISPHERE_FIGURE = "accuracy_hemisphere.png"
VPTREE_CLASSIFIER_FILE = "vocabulary_tree.npz"
VPTREE_OBSERVATION_FILE = "observation_model.npz"
VPTREE_SUMMARY_FILE = "vptree.json"
#: The VP-tree's outputs (V, C) on each test model at X_rho (the closed loop reads them).
VPTREE_OUTPUTS_FILE = "xrho_outputs.npz"

#: The configuration sections the keys of the train, classifier_eval and vptree stages hash
#: (here, with no torch, so that the stage graph is read without loading the stages' code).
TRAIN_SECTIONS = ("seed", "dataset", "camera", "render", "train")
EVAL_SECTIONS = ("seed", "camera", "render", "viewpoints")
VPTREE_SECTIONS = ("seed", "camera", "render", "viewpoints", "vptree")
#: The VP-tree's observation model's name (its array in :data:`VPTREE_OBSERVATION_FILE`).
VPTREE_MODEL_NAME = "vptree"


def confusion_file(views: str, suffix: str) -> str:
    """``confusion_xrho.csv`` and the like: a classifier_eval confusion over ``views``."""
    return f"confusion_{views}.{suffix}"


@dataclass(frozen=True)
class SingleViewAccuracy:
    """The classifier's single-view accuracy on the test models over one set of views."""

    images: int
    accuracy: float
    chance: float


@dataclass(frozen=True)
class SingleViewMetrics:
    """``W/classifier_eval/metrics.json``: over the test viewpoints X_rho and the whole sphere
    (``raw`` holds the rest: per-class accuracy, per-viewpoint accuracy, checkpoint hash)."""

    xrho: SingleViewAccuracy
    sphere: SingleViewAccuracy
    raw: dict[str, Any]


def load_single_view_metrics(folder: str | Path) -> SingleViewMetrics:
    """The classifier_eval stage's metrics, checked; an :class:`ArtefactError` names what is
    missing."""
    path = Path(folder) / METRICS_FILE
    data = read_json(path)
    parts = {}
    for key in ("xrho", "sphere"):
        part = data.get(key) if isinstance(data, dict) else None
        try:
            parts[key] = SingleViewAccuracy(int(part["images"]), float(part["accuracy"]),
                                            float(part["chance"]))
        except (KeyError, TypeError, ValueError):
            raise ArtefactError(f"{path}: '{key}' needs images, accuracy and chance") from None
    return SingleViewMetrics(parts["xrho"], parts["sphere"], data)


@dataclass(frozen=True)
class VPTreeSummary:
    """``W/vptree/vptree.json``: the VP-tree's single-view accuracy at X_rho on the test and the
    volume models, chance and its belief's likelihood temperature (None where the summary does
    not hold it: the temperature from a workspace before the belief correction)."""

    accuracy_test_xrho: float | None
    accuracy_volume_xrho: float | None
    chance: float | None
    raw: dict[str, Any]
    temperature: float | None = None


def load_vptree_summary(folder: str | Path) -> VPTreeSummary:
    path = Path(folder) / VPTREE_SUMMARY_FILE
    data = read_json(path)
    if not isinstance(data, dict):
        raise ArtefactError(f"{path}: not a JSON object")

    def number(key: str) -> float | None:
        value = data.get(key)
        return None if value is None else float(value)

    return VPTreeSummary(number("accuracy_test_xrho"), number("accuracy_volume_xrho"),
                         number("chance"), data, number("temperature"))


@dataclass(frozen=True)
class XrhoProbabilities:
    """``W/classifier_eval/probabilities.npz``: the classifier's class probabilities (V, C) at
    X_rho of each volume and test model (the xrho stage's images), by model file (a model's
    identity: nothing here reads its label)."""

    by_file: dict[str, np.ndarray]

    def of(self, model: ModelEntry) -> np.ndarray:
        """The probabilities (V, C) of one model; a model not classified is an ArtefactError."""
        try:
            return self.by_file[model.file]
        except KeyError:
            raise ArtefactError(f"no X_rho outputs of {model.file} (the volume and test "
                                "models only)") from None


def load_volume_probabilities(folder: str | Path) -> XrhoProbabilities:
    """The classifier_eval stage's probabilities at X_rho of the *volume* models only: the test
    models' arrays of the same file are not read (the learned baseline trains on held-out
    models only)."""
    arrays = load_npz(Path(folder) / PROBABILITIES_FILE, keys=("volume_files", "volume_xrho"))
    return XrhoProbabilities(dict(zip((str(f) for f in arrays["volume_files"]),
                                      arrays["volume_xrho"], strict=True)))


def load_xrho_probabilities(folder: str | Path, name: str = PROBABILITIES_FILE
                            ) -> XrhoProbabilities:
    """The classifier_eval stage's probabilities at X_rho of the volume and test models (or
    the vptree stage's outputs on the test models: ``name`` :data:`VPTREE_OUTPUTS_FILE`)."""
    arrays = load_npz(Path(folder) / name)
    by_file: dict[str, np.ndarray] = {}
    for kind, files in (("xrho", "files"), ("volume_xrho", "volume_files")):
        if kind in arrays:
            by_file.update(zip((str(f) for f in arrays[files]), arrays[kind], strict=True))
    return XrhoProbabilities(by_file)
