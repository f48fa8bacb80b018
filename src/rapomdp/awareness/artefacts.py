"""The artefacts of the saliency, volume and observe stages: their names, and the readers the
report, the command line and later stages go through (NumPy and JSON only: no torch).

``W/saliency/``: ``maps/<class>/<model>.npz`` (:func:`saliency_map_file`), :data:`SALIENCY_FILE`.
``W/volume/``: ``<class>.npz`` (:func:`volume_file`), :data:`VOLUME_FILE`.
``W/observe/``: :data:`OBSERVATION_FILE` (every observation model (V, C, C) by name, ``models``,
``classes``, ``scores``, ``directions``, ..., and per model ``first_view_<name>``: the model of
the belief's first update, :data:`FIRST_VIEW_PREFIX`), :data:`QUALITY_CSV` / :data:`QUALITY_MD` (the
self-awareness table, :func:`load_quality`), :data:`CALIBRATION_FILE`,
:data:`CALIBRATION_FIGURE`, :data:`TIMING_FILE`.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rapomdp.io import ArtefactError, load_npz, read_json
from rapomdp.recognition.artefacts import TRAIN_SECTIONS, VPTREE_SUMMARY_FILE

SALIENCY_FILE = "saliency.json"
VOLUME_FILE = "volume.json"
OBSERVATION_FILE = "observation_models.npz"
#: Prefix of each model's first-update array in :data:`OBSERVATION_FILE`: the model itself
#: (every view, the first included, is tempered alike since the first-view-in-full correction
#: was retired, docs/decisions/0003); written so that the artefact stays as it was, read by no
#: stage.
FIRST_VIEW_PREFIX = "first_view_"
#: A model's declared-confidence temperature (a scalar; absent: 1, the belief as it is) in
#: :data:`OBSERVATION_FILE`: what a policy reports is its belief ** a, renormalised, a fitted
#: where held-out walks stop.
DECLARED_PREFIX = "declared_temperature_"
#: The stop thresholds the declared confidence was also fitted at one by one (T,), and each
#: model's a at each (``declared_threshold_temperatures_<name>``, (T,)): a policy that stops at
#: a belief threshold of its own (Random) reports with the a of that threshold.
DECLARED_THRESHOLDS = "declared_thresholds"
DECLARED_THRESHOLD_PREFIX = "declared_threshold_temperatures_"
QUALITY_CSV = "quality.csv"
QUALITY_MD = "quality.md"
VALIDATION_CSV = "validation.csv"
VALIDATION_MD = "validation.md"
CALIBRATION_FILE = "calibration.json"
CALIBRATION_FIGURE = "calibration.png"
TIMING_FILE = "timing.json"
#: The configuration sections the keys of the saliency, volume and observe stages
#: hash (here, with no torch, so that the stage graph is read without loading their code).
SALIENCY_SECTIONS = (*TRAIN_SECTIONS, "saliency", "volume")
VOLUME_SECTIONS = ("volume",)
OBSERVE_SECTIONS = (*TRAIN_SECTIONS, "viewpoints", "observe")
#: The self-awareness table's columns: the model's name, then its scores on the test models.
QUALITY_COLUMNS = ("model", "log_likelihood", "brier", "auc", "mean_p_correct", "accuracy")


def saliency_map_file(class_name: str, model_id: str) -> Path:
    """A volume model's saliency maps, relative to ``W/saliency``."""
    return Path("maps") / class_name / f"{model_id}.npz"


def volume_file(class_name: str) -> str:
    """A class's saliency volume, in ``W/volume``."""
    return f"{class_name}.npz"


def load_quality(folder: str | Path, name: str = QUALITY_CSV) -> list[dict[str, float | str]]:
    """The observe stage's self-awareness table (``quality.csv``, or its held-out validation
    ``validation.csv``): one row per observation model, its scores as floats."""
    path = Path(folder) / name
    try:
        with open(path, newline="") as handle:
            rows = list(csv.DictReader(handle))
    except OSError as exc:
        raise ArtefactError(f"{path}: cannot read ({exc.strerror})") from None
    try:
        return [{"model": r["model"], **{k: float(r[k]) for k in QUALITY_COLUMNS[1:]}}
                for r in rows]
    except (KeyError, TypeError, ValueError):
        raise ArtefactError(f"{path}: expected the columns {', '.join(QUALITY_COLUMNS)}") from None


def load_softmax_temperature(observe_dir: str | Path) -> float:
    """The classifier output's temperature the observe stage fitted on the volume models
    (Static's belief); 1 for a workspace from before it was fitted."""
    data = load_npz(Path(observe_dir) / OBSERVATION_FILE)
    return float(np.asarray(data["softmax_temperature"])) if "softmax_temperature" in data \
        else 1.0


@dataclass(frozen=True)
class RAChoice:
    """Which RA variant is RA-POMDP's model ``ra`` (calibration.json): ``variant`` (``ra`` is
    the array of ``ra_<variant>``), the ``configured`` ``observe.ra_model`` and ``method``, what
    the variant's fit is (``logistic``, ``salient_view_transfer``, ``held_out_mixture``, ...);
    the choice's ``rule`` (``configured``, ``mixture`` or ``too little evidence``) and
    ``reason`` (calibration.json's ``ra_model_choice``; empty in a workspace from before it);
    with the mixture, each variant's ``weights``."""

    variant: str
    configured: str
    method: str
    rule: str = ""
    reason: str = ""
    weights: dict[str, float] = field(default_factory=dict)

    @property
    def model(self) -> str:
        return f"ra_{self.variant}"


def load_ra_choice(observe_dir: str | Path) -> RAChoice:
    """The observe stage's choice of RA-POMDP's model, from its :data:`CALIBRATION_FILE`."""
    path = Path(observe_dir) / CALIBRATION_FILE
    data = read_json(path)
    try:
        variant = str(data["ra_model"])
        variants = data.get("variants", {})
        method = variants.get(f"ra_{variant}", {}).get("method", data.get("method", ""))
        made = data.get("ra_model_choice", {})
        weights = variants.get(f"ra_{variant}", {}).get("weights", {})
        return RAChoice(variant, str(data.get("ra_model_configured", variant)), str(method),
                        str(made.get("rule", "")), str(made.get("reason", "")),
                        {str(k): float(w) for k, w in weights.items()})
    except (KeyError, TypeError, AttributeError):
        raise ArtefactError(f"{path}: expected the key ra_model (the RA variant chosen) and "
                            f"variants by name") from None


def load_declared_confidence(observe_dir: str | Path, vptree_dir: str | Path | None = None
                             ) -> dict[str, dict[str, Any]]:
    """The declared confidence's held-out record per model (``calibration.json:
    declared_confidence``, and ``vptree`` from ``vptree.json`` when ``vptree_dir`` holds one):
    empty for a workspace from before it."""
    records = dict(read_json(Path(observe_dir) / CALIBRATION_FILE).get("declared_confidence",
                                                                         {}))
    vptree = Path(vptree_dir) / VPTREE_SUMMARY_FILE if vptree_dir is not None else None
    if vptree is not None and vptree.is_file() and read_json(vptree).get("declared_confidence"):
        records["vptree"] = read_json(vptree)["declared_confidence"]
    return records
