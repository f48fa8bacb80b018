"""The report's self-awareness helpers: a reliability diagram's data with its counts, and which
observation models are one model."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

from rapomdp.awareness.report import (
    RELIABILITY_COLUMNS,
    identical_models,
    reliability_rows,
    write_reliability_csv,
)
from rapomdp.recognition.belief import reliability, temper


def test_the_reliability_data_carries_every_bins_count(tmp_path: Path) -> None:
    confidence = np.array([0.95] * 7 + [0.55, 0.05, 0.06])
    correct = np.array([True] * 6 + [False, True, False, False])
    curves = {"RA-POMDP": reliability(confidence, correct, 10)}
    rows = reliability_rows(curves)
    assert [r["count"] for r in rows] == [2, 0, 0, 0, 0, 1, 0, 0, 0, 7]
    assert rows[9]["observed"] == 6 / 7 and rows[9]["mean_predicted"] == pytest.approx(0.95)
    assert (rows[0]["bin_low"], rows[0]["bin_high"]) == (0.0, 0.1)
    assert np.isnan(rows[1]["observed"])  # an empty bin has no accuracy
    path = write_reliability_csv(curves, tmp_path / "belief_reliability.csv")
    with open(path, newline="") as handle:
        read = list(csv.DictReader(handle))
    assert list(read[0]) == list(RELIABILITY_COLUMNS)
    assert [int(r["count"]) for r in read] == [r["count"] for r in rows]
    assert sum(int(r["count"]) for r in read) == confidence.size
    assert [p.name for p in tmp_path.iterdir()] == ["belief_reliability.csv"]  # atomic


def test_models_that_are_one_model_are_grouped_whatever_their_temperature() -> None:
    rng = np.random.default_rng(0)
    chosen = rng.dirichlet(np.ones(3), size=(4, 3))  # (V, C, C)
    other = rng.dirichlet(np.ones(3), size=(4, 3))
    # the artefact holds tempered models; ra is the chosen variant, tempered alike
    observe = {"models": np.array(["ra", "ra_paper", "ra_transfer", "ra_area", "blackbox"]),
               "temperatures": np.array([0.5, 0.7, 0.5, 0.9, 1.0]),
               "ra": temper(chosen, 0.5), "ra_paper": temper(other, 0.7),
               "ra_transfer": temper(chosen, 0.5), "ra_area": temper(other, 0.9),
               "blackbox": chosen * 0 + 1 / 3}
    assert identical_models(observe) == [["ra", "ra_transfer"], ["ra_paper", "ra_area"]]
    observe["ra_area"] = temper(other + 1e-3 * (other > 0.5), 0.9) / temper(
        other + 1e-3 * (other > 0.5), 0.9).sum(axis=2, keepdims=True)
    assert identical_models(observe) == [["ra", "ra_transfer"]]


def test_the_declared_confidence_table_lists_the_methods_models_fitted_held_out(tmp_path):
    from rapomdp.awareness.report import declared_confidence_cells
    from rapomdp.io import write_json_atomic

    def record(a: float, groups: list[int]) -> dict:
        return {"temperature": a, "groups": groups, "accuracy": 0.7, "confidence": 0.8,
                "ece": 0.12, "declared_confidence": 0.71, "declared_ece": 0.05}

    observe, vptree = tmp_path / "observe", tmp_path / "vptree"
    observe.mkdir()
    vptree.mkdir()
    write_json_atomic(observe / "calibration.json", {"declared_confidence": {
        "ra": record(0.6, [0, 1, 2]), "classifier": record(0.7, []),  # one group: no row
        "blackbox": record(0.5, [0, 1])}})  # not a method's model
    write_json_atomic(vptree / "vptree.json", {"declared_confidence": {
        **record(0.8, [0, 1]), "declared_ece_if_calibrated": 0.0412}})
    header, rows = declared_confidence_cells(observe, vptree)
    assert header[1] == "a" and len(header) == len(rows[0])
    assert header[-1] == "ECE if calibrated (95 %)"
    assert [r[:2] for r in rows] == [["ra", "0.600"], ["vptree", "0.800"]]
    # a record from before the floor shows a dash; one with it, the floor
    assert rows[0][2:] == ["0.700", "0.800", "0.120", "0.710", "0.050", "—"]
    assert rows[1][-1] == "0.041"
    write_json_atomic(observe / "calibration.json", {})  # a workspace from before the option
    assert declared_confidence_cells(observe, None)[1] == []
