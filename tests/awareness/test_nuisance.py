"""The per-object nuisance belief: calibrated on planted per-object effects where naive Bayes is
not, naive Bayes itself on independent evidence, fitted by EM out of sample."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.evidence import Evidence
from rapomdp.awareness.nuisance import (
    NuisanceModel,
    fit_nuisance_models,
    nuisance_belief_models,
    object_log_likelihoods,
    out_of_sample_log_likelihoods,
)
from rapomdp.awareness.observation import BlackBoxObservationModel, single_view_marginal
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.recognition.belief import (
    expected_calibration_error,
    fold_of_rows,
    held_out_groups,
    held_out_walks,
    walk_log_beliefs,
)

CLASSES = 4
VIEWS = 32


def _planted(atypical: float, seed: int, per_class: int = 30) -> tuple[Evidence, np.ndarray]:
    """Objects of 4 classes in 3 groups: a typical object is right at each view with
    probability 0.8 (errors uniform); an atypical one (probability ``atypical``) is its next
    class's look-alike, labelled as that class at 80 % of its views. Views are independent
    given the object. Also returns which objects are atypical."""
    rng = np.random.default_rng(seed)
    labels, predicted, odd = [], [], []
    for c in range(CLASSES):
        for _ in range(per_class):
            unusual = rng.random() < atypical
            p = np.full(CLASSES, 0.2 / (CLASSES - 1))
            p[c] = 0.8
            if unusual:
                p = np.full(CLASSES, 0.1 / (CLASSES - 2))
                p[(c + 1) % CLASSES], p[c] = 0.8, 0.1
            labels.append(c)
            predicted.append(rng.choice(CLASSES, size=VIEWS, p=p))
            odd.append(unusual)
    labels_a = np.array(labels)
    groups = np.arange(labels_a.size) % 3
    return Evidence(labels_a, np.stack(predicted), groups), np.array(odd)


def _blackbox(part: Evidence, names=None) -> dict[str, np.ndarray]:
    return {"blackbox": BlackBoxObservationModel(part.labels, part.predicted,
                                                 [str(c) for c in range(CLASSES)],
                                                 1.0).probabilities}


def _held_out_walk_calibration(evidence: Evidence, belief: str) -> dict[str, float]:
    """After six views of held-out walks (each group scored by the models fitted on the
    others): accuracy, confidence − accuracy, ECE and the log loss over every step."""
    masks = held_out_groups(evidence.labels, evidence.groups)
    row_model = fold_of_rows(masks, len(evidence.labels))
    walks, walk_row = held_out_walks(row_model, fibonacci_directions(VIEWS, hemisphere=True),
                                     np.random.default_rng(1), 6, 16, 8)
    if belief == "naive":
        models = [_blackbox(evidence.subset(~m))["blackbox"] for m in masks]
        priors = None
    else:
        _, folds = nuisance_belief_models(evidence, masks, _blackbox, ["blackbox"], 1.0)
        models = [f["blackbox"].probabilities for f in folds]
        priors = [f["blackbox"].prior for f in folds]
    log_b = walk_log_beliefs(1.0, models, row_model, evidence.predicted, walks, walk_row,
                             priors=priors)
    true = evidence.labels[walk_row]
    last = np.exp(log_b[:, -1])
    confidence, right = last.max(axis=1), last.argmax(axis=1) == true
    return {"accuracy": float(right.mean()), "gap": float(confidence.mean() - right.mean()),
            "ece": expected_calibration_error(confidence, right),
            "log_loss": float(-np.mean(log_b[np.arange(len(walks)), :, true])),
            "beliefs": np.exp(log_b)}


def test_on_a_planted_per_object_effect_the_nuisance_belief_is_calibrated_and_naive_is_not():
    evidence, _ = _planted(0.3, seed=0)
    naive = _held_out_walk_calibration(evidence, "naive")
    nuisance = _held_out_walk_calibration(evidence, "nuisance")
    assert naive["gap"] > 0.15 and naive["ece"] > 0.15  # naive Bayes counts one object often
    assert abs(nuisance["gap"]) < 0.05 and nuisance["ece"] < 0.05
    assert nuisance["log_loss"] < naive["log_loss"] - 0.15
    assert nuisance["accuracy"] >= naive["accuracy"] - 0.02


def test_on_independent_evidence_the_nuisance_belief_is_naive_bayes():
    evidence, _ = _planted(0.0, seed=1)
    naive = _held_out_walk_calibration(evidence, "naive")
    nuisance = _held_out_walk_calibration(evidence, "nuisance")
    np.testing.assert_allclose(nuisance["beliefs"], naive["beliefs"], atol=1e-6)
    fitted = fit_nuisance_models(evidence, _blackbox, ["blackbox"], 1.0)["blackbox"]
    assert fitted.weight < 1e-9 and fitted.responsibilities.max() < 1e-6


def test_em_finds_the_planted_atypical_objects_and_their_look_alike_class():
    evidence, odd = _planted(0.25, seed=2)
    model = fit_nuisance_models(evidence, _blackbox, ["blackbox"], 1.0)["blackbox"]
    assert isinstance(model, NuisanceModel)
    assert model.weight == pytest.approx(odd.mean(), abs=0.03)
    assert np.array_equal(model.responsibilities > 0.5, odd)
    idx = np.arange(CLASSES)
    # atypical rows: the next class's label most often; typical rows refitted on the typical
    assert np.array_equal(model.atypical[0].argmax(axis=1), (idx + 1) % CLASSES)
    assert np.all(np.abs(model.typical[0, idx, idx] - 0.8) < 0.03)
    # the typed model, its prior and its one-view marginal
    p = model.probabilities
    assert p.shape == (VIEWS, 2 * CLASSES, CLASSES) and np.allclose(p.sum(axis=2), 1.0)
    np.testing.assert_allclose(model.prior[:CLASSES], (1 - model.weight) / CLASSES)
    np.testing.assert_allclose(model.prior.sum(), 1.0)
    np.testing.assert_allclose(single_view_marginal(p, model.prior), model.single_view)
    summary = model.to_dict()
    assert summary["objects"] == len(odd) and summary["atypical_objects"] == pytest.approx(
        odd.sum(), abs=0.5)


def test_the_typical_likelihood_of_an_object_comes_from_models_fitted_without_its_group():
    evidence, _ = _planted(0.25, seed=3, per_class=6)
    seen: list[int] = []

    def fit(part: Evidence, names=None) -> dict[str, np.ndarray]:
        seen.append(len(part.labels))
        return _blackbox(part)

    scored = out_of_sample_log_likelihoods(evidence, fit, ["blackbox"])["blackbox"]
    assert seen == [16, 16, 16]  # three folds, each fitted on the other two groups
    held = evidence.groups == 1
    expected = object_log_likelihoods(_blackbox(evidence.subset(~held))["blackbox"],
                                      evidence.labels[held], evidence.predicted[held])
    np.testing.assert_allclose(scored[held], expected)
