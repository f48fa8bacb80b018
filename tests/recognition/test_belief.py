"""The multi-view belief's temperature: planted independent and repeated evidence, the walks,
the held-out folds and the calibration report."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import logsumexp

from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.recognition.belief import (
    DECLARED_STOP_THRESHOLDS,
    belief_log_loss,
    calibrated_ece,
    calibrated_ece_draws,
    declared_confidence,
    expected_calibration_error,
    fit_declared_temperature,
    fit_temperature,
    fold_of_rows,
    held_out_groups,
    held_out_walks,
    random_walks,
    stop_steps,
    stopped_log_beliefs,
    stops_declared_confidence,
    walk_calibration,
    walk_log_beliefs,
)


def _planted_model(views: int, classes: int, rng: np.random.Generator) -> np.ndarray:
    p = rng.dirichlet(np.ones(classes), size=(views, classes))
    p = 0.4 * p + 0.6 * np.eye(classes)[None]
    return p / p.sum(axis=2, keepdims=True)


def _draw_labels(p: np.ndarray, labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    cdf = np.cumsum(p[:, labels], axis=2)  # (V, N, C)
    u = rng.random(cdf.shape[:2])[..., None]
    return (u > cdf).sum(axis=2).T.clip(max=p.shape[1] - 1)  # (N, V)


def _planted_walks(rng: np.random.Generator) -> tuple[int, int, np.ndarray, np.ndarray,
                                                      np.ndarray, np.ndarray, np.ndarray]:
    """Independent evidence from a planted 20-view, 3-class model: 400 rows of labels drawn at
    every view, 4 walks of 6 random views a row (views, rows, model, labels, predicted,
    walk rows, walks)."""
    views, classes, rows = 20, 3, 400
    p = _planted_model(views, classes, rng)
    labels = rng.integers(0, classes, rows)
    predicted = _draw_labels(p, labels, rng)
    walk_row = np.repeat(np.arange(rows), 4)
    walks = np.stack([rng.permutation(views)[:6] for _ in walk_row])
    return views, rows, p, labels, predicted, walk_row, walks


def test_temperature_leaves_independent_evidence_alone_and_shrinks_duplicated_evidence():
    rng = np.random.default_rng(3)
    views, rows, p, labels, predicted, walk_row, walks = _planted_walks(rng)
    independent = fit_temperature([p], np.zeros(rows, np.int64), labels, predicted, walks,
                                  walk_row)
    assert independent == pytest.approx(1.0, abs=0.12)
    # every odd viewpoint repeats the label of the even one before it; walks visit both
    duplicated = predicted.copy()
    duplicated[:, 1::2] = duplicated[:, 0::2]
    pairs = np.stack([rng.permutation(views // 2)[:3] for _ in walk_row])
    walks = np.stack([2 * pairs, 2 * pairs + 1], axis=2).reshape(len(walk_row), 6)
    shrunk = fit_temperature([p], np.zeros(rows, np.int64), labels, duplicated, walks, walk_row)
    assert 0.3 < shrunk < 0.75
    loss = [belief_log_loss(t, [p], np.zeros(rows, np.int64), labels, duplicated, walks,
                            walk_row) for t in (1.0, shrunk)]
    assert loss[1] < loss[0]


def test_random_walks_move_to_near_unvisited_viewpoints():
    directions = fibonacci_directions(64, hemisphere=True)
    walks = random_walks(directions, np.arange(64), 5, 6, np.random.default_rng(5))
    assert walks.shape == (64, 5) and np.array_equal(walks[:, 0], np.arange(64))
    assert all(len(set(w)) == 5 for w in walks.tolist())
    step = np.einsum("ij,ij->i", directions[walks[:, :-1]].reshape(-1, 3),
                     directions[walks[:, 1:]].reshape(-1, 3))
    assert np.degrees(np.arccos(np.clip(step, -1, 1))).max() < 35


def test_after_first_leaves_independent_evidence_alone_and_discounts_only_later_views():
    rng = np.random.default_rng(13)
    views, rows, p, labels, predicted, walk_row, walks = _planted_walks(rng)
    row_model = np.zeros(rows, np.int64)
    independent = fit_temperature([p], row_model, labels, predicted, walks, walk_row,
                                  first_temperature=1.0)
    assert independent == pytest.approx(1.0, abs=0.12)
    # every later view repeats the first view's label: only the first one is evidence
    repeated = np.repeat(predicted[:, :1], views, axis=1)
    shrunk = fit_temperature([p], row_model, labels, repeated, walks, walk_row,
                             first_temperature=1.0)
    assert shrunk < 0.3
    # the first step's belief is the single-view posterior whatever the later temperature
    first = [walk_log_beliefs(t, [p], row_model, repeated, walks, walk_row, 1.0)[:, 0]
             for t in (1.0, shrunk)]
    assert np.allclose(first[0], first[1])


def test_held_out_groups_skip_a_group_whose_complement_misses_a_class():
    labels = np.array([0, 1, 0, 1, 1])
    groups = np.array([0, 0, 1, 1, 2])  # without group 0 or 1 a class is still seen; not 2's
    masks = held_out_groups(labels, groups)
    assert [m.tolist() for m in masks] == [[True, True, False, False, False],
                                           [False, False, True, True, False],
                                           [False, False, False, False, True]]
    assert held_out_groups(np.array([0, 1]), np.array([0, 0])) == []  # one group
    assert held_out_groups(np.array([0, 1]), np.array([0, 1])) == []  # each class once
    assert fold_of_rows(masks[:2], 5).tolist() == [0, 0, 1, 1, -1]


def test_held_out_walks_start_per_held_out_row_on_the_sphere():
    directions = fibonacci_directions(16, hemisphere=True)
    row_model = np.array([0, -1, 1])
    walks, walk_row = held_out_walks(row_model, directions, np.random.default_rng(2), 4, 3, 5)
    assert walk_row.tolist() == [0, 0, 0, 2, 2, 2]
    assert walks.shape == (6, 4) and walks.min() >= 0 and walks.max() < 16
    again = held_out_walks(row_model, directions, np.random.default_rng(2), 4, 3, 5)
    assert np.array_equal(again[0], walks)  # the generator's draws only


def test_walk_calibration_reports_the_naive_and_tempered_beliefs():
    rng = np.random.default_rng(8)
    views, rows, p, labels, predicted, walk_row, walks = _planted_walks(rng)
    row_model = np.zeros(rows, np.int64)
    report = walk_calibration(0.5, [p], row_model, labels, predicted, walks, walk_row)
    assert report["temperature"] == 0.5
    for label, t in (("naive", 1.0), ("tempered", 0.5)):
        assert report[f"log_loss_{label}"] == belief_log_loss(t, [p], row_model, labels,
                                                              predicted, walks, walk_row)
        last = np.exp(walk_log_beliefs(t, [p], row_model, predicted, walks, walk_row))[:, -1]
        right = last.argmax(axis=1) == labels[walk_row]
        assert report[f"belief_last_{label}"] == pytest.approx(last.max(axis=1).mean())
        assert report[f"ece_last_{label}"] == expected_calibration_error(last.max(axis=1),
                                                                         right)
        accuracy = right.mean()
    # the accuracy is the tempered belief's (renormalising P ** t can move an argmax)
    assert report["accuracy_last"] == pytest.approx(accuracy)
    # a cooler model is less sure of its first view
    assert report["belief_first_tempered"] < report["belief_first_naive"]


def test_expected_calibration_error_is_the_weighted_gap_per_bin():
    confidence = np.array([0.95, 0.95, 0.55, 0.55])
    right = np.array([True, True, True, False])
    assert expected_calibration_error(confidence, right) == pytest.approx(
        0.5 * 0.05 + 0.5 * 0.05)


def _posterior_walks(rng: np.random.Generator, walks: int = 3000, steps: int = 8,
                     classes: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """Log posteriors (E, L, C) of walks whose every view emits a label independently from a
    known model (right with 0.6, each wrong label 0.2): Bayes with that model is calibrated at
    any stop, whatever the stopping rule. And each walk's true class (E,)."""
    true = rng.integers(0, classes, walks)
    right = rng.random((walks, steps)) < 0.6
    wrong = (true[:, None] + rng.integers(1, classes, (walks, steps))) % classes
    labels = np.where(right, true[:, None], wrong)
    log_lik = np.where(labels[..., None] == np.arange(classes), np.log(0.6), np.log(0.2))
    cumulative = np.cumsum(log_lik, axis=1)
    return cumulative - logsumexp(cumulative, axis=2, keepdims=True), true


def test_walks_stop_where_the_belief_first_reaches_the_threshold_or_at_their_end():
    belief = np.array([[[0.5, 0.5], [0.8, 0.2], [0.95, 0.05]],
                       [[0.6, 0.4], [0.6, 0.4], [0.7, 0.3]]])
    log_belief = np.log(belief)
    assert stop_steps(log_belief, 0.8).tolist() == [1, 2]
    assert stop_steps(log_belief, 0.5).tolist() == [0, 0]
    final, walk = stopped_log_beliefs(log_belief, (0.8, 0.9))
    assert walk.tolist() == [0, 1, 0, 1]
    assert np.allclose(np.exp(final), belief[[0, 1, 0, 1], [1, 2, 2, 2]])


def test_the_declared_temperature_undoes_a_planted_overconfidence_where_walks_stop():
    rng = np.random.default_rng(11)
    log_belief, true = _posterior_walks(rng)
    final, walk = stopped_log_beliefs(log_belief)
    assert len(walk) == len(DECLARED_STOP_THRESHOLDS) * len(true)
    # the Bayes posterior is calibrated at any stop; counting every view three times is not
    assert fit_declared_temperature(final, true[walk]) == pytest.approx(1.0, abs=0.1)
    tripled = 3.0 * log_belief
    tripled -= logsumexp(tripled, axis=2, keepdims=True)
    final3, walk3 = stopped_log_beliefs(tripled)
    assert fit_declared_temperature(final3, true[walk3]) == pytest.approx(1 / 3, abs=0.05)
    with pytest.raises(ValueError, match="no stopped beliefs"):
        fit_declared_temperature(final[:0], true[:0])


def test_declared_confidence_is_scored_leave_one_group_out():
    rng = np.random.default_rng(12)
    log_belief, true = _posterior_walks(rng)
    tripled = 3.0 * log_belief
    tripled -= logsumexp(tripled, axis=2, keepdims=True)
    groups = np.arange(len(true)) % 3
    fit = declared_confidence(tripled, true, groups)
    assert fit.groups == (0, 1, 2) and len(fit.held_out_temperatures) == 3
    assert all(abs(a - 1 / 3) < 0.07 for a in fit.held_out_temperatures)
    assert fit.stops == len(DECLARED_STOP_THRESHOLDS) * len(true)
    assert fit.confidence - fit.accuracy > 0.1  # the tripled belief is overconfident
    assert abs(fit.declared_confidence - fit.accuracy) < 0.03
    assert fit.declared_ece < 0.5 * fit.ece
    alone = declared_confidence(tripled, true, np.zeros(len(true), np.int64))
    assert alone.groups == () and alone.held_out_temperatures == ()
    assert np.isnan(alone.declared_ece) and alone.temperature == pytest.approx(fit.temperature)


def test_either_criterion_and_every_threshold_undo_a_planted_overconfidence():
    rng = np.random.default_rng(13)
    log_belief, true = _posterior_walks(rng)
    tripled = 3.0 * log_belief
    tripled -= logsumexp(tripled, axis=2, keepdims=True)
    final, walk = stopped_log_beliefs(tripled)
    assert fit_declared_temperature(final, true[walk], criterion="confidence") == \
        pytest.approx(1 / 3, abs=0.06)
    with pytest.raises(ValueError, match="criterion must be one of log_loss, confidence"):
        fit_declared_temperature(final, true[walk], criterion="brier")
    fit = declared_confidence(tripled, true, np.arange(len(true)) % 3, criterion="confidence")
    assert fit.criterion == "confidence"
    assert fit.thresholds == DECLARED_STOP_THRESHOLDS
    # a Bayes posterior is calibrated at any stop, so every threshold's own fit is ~1/3 too
    assert all(abs(a - 1 / 3) < 0.08 for a in fit.threshold_temperatures)
    assert all(own < belief for own, belief in zip(fit.threshold_own_ece, fit.threshold_ece,
                                                   strict=True))
    assert fit.to_dict()["thresholds"] == list(DECLARED_STOP_THRESHOLDS)


def test_a_policys_own_stops_fit_the_declared_confidence_held_out_by_group():
    rng = np.random.default_rng(14)
    log_belief, true = _posterior_walks(rng)
    tripled = 3.0 * log_belief
    tripled -= logsumexp(tripled, axis=2, keepdims=True)
    # a policy's own stops: any rule (here: a step drawn per episode), no threshold
    steps = rng.integers(0, log_belief.shape[1], len(true))
    final = tripled[np.arange(len(true)), steps]
    groups = np.arange(len(true)) % 3
    fit = stops_declared_confidence(final, true, groups)
    assert fit.temperature == pytest.approx(1 / 3, abs=0.06)
    assert fit.stops == len(true) and fit.thresholds == () and fit.threshold_temperatures == ()
    assert fit.groups == (0, 1, 2) and all(abs(a - 1 / 3) < 0.08
                                           for a in fit.held_out_temperatures)
    assert fit.confidence - fit.accuracy > 0.1 and abs(fit.declared_confidence
                                                       - fit.accuracy) < 0.03
    calibrated = stops_declared_confidence(log_belief[np.arange(len(true)), steps], true,
                                           groups)
    assert calibrated.temperature == pytest.approx(1.0, abs=0.12)  # Bayes: left as it is
    alone = stops_declared_confidence(final, true, np.zeros(len(true), np.int64))
    assert alone.groups == () and np.isnan(alone.declared_ece)
    # the record: the fit, its held-out scores, per threshold (none here) and the floor
    assert list(fit.to_dict()) == [
        "temperature", "criterion", "groups", "held_out_temperatures", "stops", "accuracy",
        "confidence", "ece", "declared_confidence", "declared_ece", "thresholds",
        "threshold_temperatures", "threshold_ece", "threshold_declared_ece",
        "threshold_own_ece", "declared_ece_if_calibrated"]


def test_the_ece_of_a_calibrated_reporter_is_what_sampling_alone_gives():
    # certain and right: no draw can show an error
    assert np.all(calibrated_ece_draws(np.ones(50), draws=20) == 0.0)
    # every stop at 0.5, one bin: ECE = |R − N/2| / N with R ~ Binomial(N, 1/2), whose mean is
    # about √(N / (2π)) / N
    draws = calibrated_ece_draws(np.full(400, 0.5), draws=4000, seed=1)
    assert draws.mean() == pytest.approx(np.sqrt(400 / (2 * np.pi)) / 400, rel=0.05)
    # each draw is the ECE of those confidences against coins of them
    confidence = np.random.default_rng(2).uniform(0.3, 1.0, 300)
    rng = np.random.default_rng(7)
    coins = rng.random((5, 300)) < confidence
    assert calibrated_ece_draws(confidence, draws=5, seed=7) == pytest.approx(
        [expected_calibration_error(confidence, c) for c in coins])
    # more stops, a lower floor; the reported figure is a quantile of the draws
    few, many = calibrated_ece(confidence[:60]), calibrated_ece(np.tile(confidence, 10))
    assert many < few / 2
    assert calibrated_ece(confidence, quantile=0.5) == pytest.approx(
        np.quantile(calibrated_ece_draws(confidence), 0.5))
    with pytest.raises(ValueError, match="no confidences"):
        calibrated_ece_draws(np.array([]))
