"""The recognition stages' artefacts read back through their typed loaders."""

from __future__ import annotations

from pathlib import Path

import pytest

from rapomdp.io import ArtefactError, write_json_atomic
from rapomdp.recognition.artefacts import (
    SingleViewAccuracy,
    confusion_file,
    load_single_view_metrics,
    load_vptree_summary,
)


def test_single_view_metrics_read_back_typed_and_refuse_a_partial_file(tmp_path: Path) -> None:
    data = {"xrho": {"images": 48, "accuracy": 0.6458, "chance": 0.3333, "views": "xrho"},
            "sphere": {"images": 18, "accuracy": 0.7222, "chance": 0.3333},
            "checkpoint_config_hash": "abc"}
    write_json_atomic(tmp_path / "metrics.json", data)
    metrics = load_single_view_metrics(tmp_path)
    assert metrics.xrho == SingleViewAccuracy(48, 0.6458, 0.3333)
    assert metrics.sphere.images == 18 and metrics.raw["checkpoint_config_hash"] == "abc"
    write_json_atomic(tmp_path / "metrics.json", {"xrho": data["xrho"]})
    with pytest.raises(ArtefactError, match="'sphere' needs images, accuracy and chance"):
        load_single_view_metrics(tmp_path)
    with pytest.raises(ArtefactError, match="not found|cannot read"):
        load_single_view_metrics(tmp_path / "nowhere")
    assert confusion_file("xrho", "png") == "confusion_xrho.png"


def test_vptree_summary_gives_none_for_what_it_lacks(tmp_path: Path) -> None:
    write_json_atomic(tmp_path / "vptree.json", {"accuracy_test_xrho": None, "chance": 0.5,
                                                 "accuracy_volume_xrho": 0.75})
    summary = load_vptree_summary(tmp_path)
    assert (summary.accuracy_test_xrho, summary.accuracy_volume_xrho, summary.chance) == (
        None, 0.75, 0.5)


