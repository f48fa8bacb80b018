"""Held-out evidence and its folds: the calibrations the RA variants read, the held-out
validation table, the records a refit reads, the passive softmax temperature."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.evidence import (
    Evidence,
    recorded_evidence,
    recorded_scores,
    validation_quality,
)
from rapomdp.awareness.mixture import (
    choose_ra_variant,
)
from rapomdp.awareness.observation import (
    calibrate_correctness,
    calibrate_per_class,
)
from rapomdp.awareness.variants import fit_observation_models, leave_one_group_out
from rapomdp.config import ObserveConfig


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-z))


def test_logistic_calibration_recovers_a_planted_curve():
    rng = np.random.default_rng(0)
    s = rng.random(40_000)
    correct = rng.random(s.size) < _sigmoid(-1.0 + 3.0 * s)
    fit = calibrate_correctness(s, correct, "logistic")
    assert fit.intercept == pytest.approx(-1.0, abs=0.08)
    assert fit.slope == pytest.approx(3.0, abs=0.15)
    grid = np.linspace(0, 1, 11)
    assert np.max(np.abs(fit(grid) - _sigmoid(-1.0 + 3.0 * grid))) < 0.02


def test_isotonic_calibration_recovers_a_planted_step():
    rng = np.random.default_rng(1)
    s = rng.random(20_000)
    truth = np.where(s < 0.5, 0.3, 0.9)
    fit = calibrate_correctness(s, rng.random(s.size) < truth, "isotonic")
    assert np.abs(fit(np.array([0.2, 0.8])) - [0.3, 0.9]).max() < 0.03
    assert np.all(np.diff(fit(np.linspace(0, 1, 50))) >= 0)


def test_per_class_calibration_recovers_intercepts_and_the_shared_slope():
    rng = np.random.default_rng(2)
    intercepts = np.array([-1.5, 0.0, 1.0])
    g = rng.integers(0, 3, 60_000)
    s = rng.random(g.size)
    correct = rng.random(g.size) < _sigmoid(intercepts[g] + 2.0 * s)
    fit = calibrate_per_class(s, correct, g, 3)
    assert np.abs(fit.intercepts - intercepts).max() < 0.12
    assert fit.slope == pytest.approx(2.0, abs=0.15)


def test_held_out_validation_prefers_the_score_that_predicts_correctness():
    """Planted: class 0 is right where its 'mean' score is high, whatever the 'area' score."""
    rng = np.random.default_rng(6)
    views, classes = 64, 2
    mean = np.stack([np.linspace(0, 1, views), rng.random(views)])
    area = rng.random((classes, views))
    labels = np.repeat([0, 1], 6)
    p_right = _sigmoid(-2.0 + 5.0 * mean[labels])
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], 1 - labels[:, None])
    evidence = Evidence(labels, predicted, np.tile(np.arange(6), 2))
    cfg = ObserveConfig()
    folds = leave_one_group_out(evidence, {"mean": mean, "area": area}, ["a", "b"], cfg)
    assert len(folds) == 6 and all(held.sum() == 2 for held, _ in folds)
    rows = {r["model"]: r for r in validation_quality(evidence, folds)}
    assert rows["ra_paper"]["log_likelihood"] > rows["ra_area"]["log_likelihood"]
    assert rows["ra_paper"]["auc"] > 0.75 > rows["ra_area"]["auc"]
    choice = choose_ra_variant(evidence, folds, "area", ["a", "b"])
    assert (choice.variant, choice.rule) == ("area", "configured")
    models = fit_observation_models(evidence, {"mean": mean, "area": area}, ["a", "b"], cfg)
    assert set(models) == {"ra_paper", "ra_class", "ra_area", "ra_class_area", "classifier",
                           "blackbox"}


def _planted_area_evidence(groups: int, seed: int) -> tuple[Evidence, dict[str, np.ndarray]]:
    """Three classes whose correctness follows the 'area' score strongly; 'mean' is noise."""
    rng = np.random.default_rng(seed)
    views, classes = 96, 3
    scores = {"mean": rng.random((classes, views)), "area": rng.random((classes, views))}
    labels = np.repeat(np.arange(classes), groups)
    p_right = _sigmoid(-3.0 + 7.0 * scores["area"][labels])
    right = rng.random(p_right.shape) < p_right
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % classes)
    return Evidence(labels, predicted, np.tile(np.arange(groups), classes)), scores


def test_the_recorded_evidence_and_scores_are_what_a_refit_reads() -> None:
    artefact = {"evidence_labels": np.array([0, 1]),
                "evidence_predictions": np.array([[0, 1], [1, 1]]),
                "evidence_groups": np.array([0, 1]),
                "evidence_from_volume": np.array([True, False]),
                "scores": np.ones((2, 2)), "area_scores": np.zeros((2, 2)),
                "view_similarity": np.eye(2, dtype=np.float32)[None].repeat(2, axis=0)}
    evidence = recorded_evidence(artefact)
    assert evidence.labels.tolist() == [0, 1] and evidence.groups.tolist() == [0, 1]
    assert evidence.correct.tolist() == [[True, False], [True, True]]
    scores = recorded_scores(artefact)
    assert set(scores) == {"mean", "area", "similarity"}
    assert scores["similarity"].dtype == np.float64
    del artefact["view_similarity"]  # an artefact from before ra_transfer: no similarity
    assert set(recorded_scores(artefact)) == {"mean", "area"}


def test_softmax_temperature_recovers_a_planted_overconfidence():
    from rapomdp.awareness.temperature import fit_softmax_temperature

    rng = np.random.default_rng(21)
    logits = rng.normal(size=(4000, 5)) * 2.0
    labels = np.array([rng.choice(5, p=np.exp(z) / np.exp(z).sum()) for z in logits])
    calibrated = np.exp(logits) / np.exp(logits).sum(axis=1, keepdims=True)
    over = np.exp(3.0 * logits) / np.exp(3.0 * logits).sum(axis=1, keepdims=True)
    assert fit_softmax_temperature(calibrated, labels) == pytest.approx(1.0, abs=0.08)
    assert fit_softmax_temperature(over[:, None], labels) == pytest.approx(3.0, rel=0.08)


