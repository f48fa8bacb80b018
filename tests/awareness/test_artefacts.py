"""The observe stage's self-awareness table: written as CSV and markdown, read back as data;
its choice of RA-POMDP's model, read from calibration.json."""

from __future__ import annotations

from pathlib import Path

import pytest

from rapomdp.awareness.artefacts import (
    CALIBRATION_FILE,
    QUALITY_COLUMNS,
    RAChoice,
    load_quality,
    load_ra_choice,
    saliency_map_file,
)
from rapomdp.awareness.quality import quality_cells, write_quality
from rapomdp.io import ArtefactError, write_json_atomic

ROWS = [{"model": "ra", "log_likelihood": -0.41234567891, "brier": 0.131, "auc": 0.74,
         "mean_p_correct": 0.61, "accuracy": 0.58},
        {"model": "classifier", "log_likelihood": -0.533, "brier": 0.17, "auc": float("nan"),
         "mean_p_correct": 0.55, "accuracy": 0.58}]


def test_the_quality_table_round_trips_and_renders_once(tmp_path: Path) -> None:
    write_quality(ROWS, tmp_path / "quality.csv", tmp_path / "quality.md")
    rows = load_quality(tmp_path)
    assert [r["model"] for r in rows] == ["ra", "classifier"]
    assert rows[0]["log_likelihood"] == ROWS[0]["log_likelihood"]  # exact through the CSV
    header, cells = quality_cells(rows)
    assert len(header) == len(QUALITY_COLUMNS)
    assert cells[0] == ["ra", "-0.412", "0.131", "0.740", "0.610", "0.580"]
    assert cells[1][3] == "nan"
    markdown = (tmp_path / "quality.md").read_text().splitlines()
    assert markdown[2] == "| " + " | ".join(cells[0]) + " |"


def test_a_wrong_quality_file_is_named(tmp_path: Path) -> None:
    (tmp_path / "quality.csv").write_text("model,brier\nra,0.1\n")
    with pytest.raises(ArtefactError, match="quality.csv: expected the columns model, "):
        load_quality(tmp_path)
    with pytest.raises(ArtefactError, match="cannot read"):
        load_quality(tmp_path / "nowhere")
    assert saliency_map_file("cup", "m1") == Path("maps/cup/m1.npz")


def test_the_ra_choice_is_read_with_its_variants_method(tmp_path: Path) -> None:
    write_json_atomic(tmp_path / CALIBRATION_FILE, {
        "ra_model": "transfer", "ra_model_configured": "auto", "method": "logistic",
        "variants": {"ra_paper": {"method": "logistic"},
                     "ra_transfer": {"method": "salient_view_transfer"}}})
    choice = load_ra_choice(tmp_path)
    assert choice == RAChoice("transfer", "auto", "salient_view_transfer")
    assert choice.model == "ra_transfer"
    # an older file without the variants: the top-level method is the chosen model's
    write_json_atomic(tmp_path / CALIBRATION_FILE, {"ra_model": "paper", "method": "isotonic"})
    assert load_ra_choice(tmp_path) == RAChoice("paper", "paper", "isotonic")
    write_json_atomic(tmp_path / CALIBRATION_FILE, {"method": "logistic"})
    with pytest.raises(ArtefactError, match="calibration.json: expected the key ra_model"):
        load_ra_choice(tmp_path)
