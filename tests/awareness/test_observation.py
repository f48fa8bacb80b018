"""Observation models: valid distributions, RA monotone in the score, quality metrics."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.observation import (
    BlackBoxObservationModel,
    ClassifierObservationModel,
    MixtureObservationModel,
    ObservationModel,
    RAObservationModel,
    calibrate_correctness,
    calibrate_per_class,
    wrong_label_distribution,
)

CLASSES = ["a", "b", "c"]


def synthetic(seed: int = 0, views: int = 40) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Scores (C, V) and outcomes where P(correct) = 0.2 + 0.7 * score."""
    rng = np.random.default_rng(seed)
    scores = rng.random((3, views))
    correct = rng.random((3, views)) < 0.2 + 0.7 * scores
    wrong = (np.arange(3)[:, None] + rng.integers(1, 3, (3, views))) % 3
    predicted = np.where(correct, np.arange(3)[:, None], wrong)
    return scores, correct, predicted


@pytest.mark.parametrize("method", ["logistic", "isotonic"])
def test_calibration_is_monotone_and_follows_the_data(method):
    scores, correct, _ = synthetic(views=400)
    calibration = calibrate_correctness(scores, correct, method)
    grid = np.linspace(0, 1, 101)
    p = calibration(grid)
    assert np.all(np.diff(p) >= -1e-12)
    assert p[5] < 0.4 and p[95] > 0.75  # truth: 0.235 and 0.865


def test_logistic_calibration_of_a_falling_trend_is_flat():
    s = np.linspace(0, 1, 200)
    calibration = calibrate_correctness(s, s < 0.5, "logistic")
    assert calibration.slope == 0.0
    assert calibration(np.array([0.0, 1.0])) == pytest.approx([0.5, 0.5], abs=1e-6)


def test_ra_rows_sum_to_one_and_correct_label_rises_with_the_score():
    scores, correct, predicted = synthetic()
    calibration = calibrate_correctness(scores, correct)
    wrong = wrong_label_distribution(np.repeat(np.arange(3), 40), predicted, 3, 1.0)
    model = RAObservationModel(scores, calibration, wrong, CLASSES)
    p = model.probabilities
    assert p.shape == (40, 3, 3)
    assert np.allclose(p.sum(axis=2), 1.0) and np.all(p > 0)
    for c in range(3):
        order = np.argsort(scores[c])
        assert np.all(np.diff(model.correct_probability()[order, c]) >= 0)
    assert model.likelihood(5, 1).shape == (3,)


def test_per_class_calibration_separates_class_difficulty_from_the_score():
    rng = np.random.default_rng(2)
    scores = rng.random((3, 300))
    base = np.array([-2.0, 0.0, 2.0])  # class 0 hard, class 2 easy; same score effect
    p_true = 1 / (1 + np.exp(-(base[:, None] + 2.0 * scores)))
    correct = rng.random((3, 300)) < p_true
    fit = calibrate_per_class(scores, correct, np.repeat(np.arange(3)[:, None], 300, axis=1), 3)
    assert fit.slope == pytest.approx(2.0, abs=0.7)
    assert fit.intercepts[0] < fit.intercepts[1] < fit.intercepts[2]
    p = fit(np.tile(np.linspace(0, 1, 11), (3, 1)))
    assert p.shape == (3, 11) and np.all(np.diff(p, axis=1) >= 0)


def test_wrong_label_distribution_has_zero_diagonal_and_follows_confusion():
    true = np.array([0, 0, 0, 0, 1, 2])
    pred = np.array([0, 1, 1, 2, 1, 2])
    wrong = wrong_label_distribution(true, pred, 3, 0.0)
    assert np.allclose(np.diag(wrong), 0) and np.allclose(wrong.sum(axis=1), 1)
    assert wrong[0] == pytest.approx([0, 2 / 3, 1 / 3])
    assert wrong[1] == pytest.approx([0.5, 0, 0.5])  # never wrong: uniform


def test_classifier_model_counts_per_viewpoint_with_pseudo_counts():
    true = np.array([0, 1, 2])
    pred = np.array([[0, 1], [1, 1], [0, 2]])  # (models, viewpoints)
    model = ClassifierObservationModel(true, pred, CLASSES, pseudo_count=0.5)
    p = model.probabilities
    assert p.shape == (2, 3, 3) and np.allclose(p.sum(axis=2), 1)
    assert p[0, 2] == pytest.approx([1.5 / 2.5, 0.5 / 2.5, 0.5 / 2.5])
    assert p[1, 0] == pytest.approx([0.5 / 2.5, 1.5 / 2.5, 0.5 / 2.5])
    black = BlackBoxObservationModel(true, pred, CLASSES, pseudo_count=0.5)
    assert np.allclose(black.probabilities[0], black.probabilities[1])
    assert black.probabilities[0, 2] == pytest.approx([1.5 / 3.5, 0.5 / 3.5, 1.5 / 3.5])


def test_observation_model_rejects_bad_rows():
    with pytest.raises(ValueError, match="rows summing to 1"):
        ObservationModel(np.full((2, 3, 3), 0.5), CLASSES)
    with pytest.raises(ValueError, match=r"must be \(V, 3, 3\)"):
        ObservationModel(np.full((2, 2, 2), 0.5), CLASSES)






def test_isotonic_calibration_pools_adjacent_violators_exactly():
    calibration = calibrate_correctness(np.array([0.1, 0.2, 0.3, 0.4]),
                                        np.array([True, False, True, True]), "isotonic")
    np.testing.assert_allclose(calibration.knots_y, [0.5, 1.0])
    np.testing.assert_allclose(calibration.knots_x, [0.15, 0.35])


def test_a_mixture_is_the_weighted_sum_of_its_tables_and_refuses_bad_weights() -> None:
    rng = np.random.default_rng(1)
    tables = {name: rng.dirichlet(np.ones(3), size=(5, 3)) for name in ("ra_a", "ra_b")}
    models = {name: ObservationModel(t, CLASSES) for name, t in tables.items()}
    mixture = MixtureObservationModel(models, {"ra_a": 0.25, "ra_b": 0.75}, CLASSES)
    assert np.allclose(mixture.probabilities, 0.25 * tables["ra_a"] + 0.75 * tables["ra_b"])
    assert mixture.calibration.to_dict() == {"method": "held_out_mixture",
                                             "weights": {"ra_a": 0.25, "ra_b": 0.75}}
    with pytest.raises(ValueError, match="must be a distribution"):
        MixtureObservationModel(models, {"ra_a": 0.5, "ra_b": 0.6}, CLASSES)
    with pytest.raises(ValueError, match="weights for models not given"):
        MixtureObservationModel(models, {"ra_c": 1.0}, CLASSES)
