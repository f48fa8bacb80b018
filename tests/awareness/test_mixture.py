"""RA-POMDP's model: the mixture's weights on held-out labels, its table, its fallback."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.evidence import (
    MIN_HELD_OUT_OBJECTS,
    Evidence,
    validation_quality,
)
from rapomdp.awareness.mixture import (
    ROBUST_RA_VARIANT,
    choose_ra_variant,
    fit_mixture_weights,
    ra_mixture_folds,
)
from rapomdp.awareness.observation import (
    ObservationModel,
)
from rapomdp.awareness.variants import leave_one_group_out
from rapomdp.config import ObserveConfig
from rapomdp.geometry.viewsphere import fibonacci_directions
from tests.awareness.test_evidence import _planted_area_evidence


def test_the_mixture_records_every_variants_held_out_table_and_the_best() -> None:
    evidence, scores = _planted_area_evidence(4, 8)
    classes = ["a", "b", "c"]
    folds = leave_one_group_out(evidence, scores, classes, ObserveConfig())
    choice = choose_ra_variant(evidence, folds, "mixture", classes)
    assert (choice.variant, choice.rule) == ("mixture", "mixture")
    assert not choice.too_little_evidence
    assert choice.best in {"area", "class_area"}  # the score that carries correctness
    assert choice.objects_per_class == {"a": 4, "b": 4, "c": 4}
    robust = choice.held_out[ROBUST_RA_VARIANT]
    assert robust["difference_to_best"] < -robust["standard_error"] < 0  # beyond one SE
    best = choice.held_out[choice.best]
    assert best["mean_log_likelihood"] == max(r["mean_log_likelihood"]
                                              for r in choice.held_out.values())
    assert best["difference_to_best"] == 0.0
    # the per-object figures average to the pooled held-out table's
    pooled = {r["model"]: r for r in validation_quality(evidence, folds)}
    assert best["mean_log_likelihood"] == pytest.approx(
        float(pooled[f"ra_{choice.best}"]["log_likelihood"]), abs=1e-9)
    assert choice.reason == (f"the RA variants averaged with weights fitted on the held-out "
                             f"labels (12 held-out objects; '{choice.best}' alone is the best)")
    assert choice.to_dict()["without_each_group"] == {}


def test_the_held_out_chooser_says_when_there_is_too_little_evidence() -> None:
    evidence, scores = _planted_area_evidence(4, 9)
    classes = ["a", "b", "c"]
    one = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    choice = choose_ra_variant(one, leave_one_group_out(one, scores, classes, ObserveConfig()),
                               "mixture", classes)
    assert (choice.variant, choice.rule) == (ROBUST_RA_VARIANT, "too little evidence")
    assert choice.too_little_evidence and choice.objects_per_class == {"a": 0, "b": 0, "c": 0}
    assert choice.reason.startswith("too little held-out evidence to choose: class 'a' (0)")
    # class c with one volume model only: its one object is never held out, so too little
    keep = (evidence.labels != 2) | (evidence.groups == 0)
    short = evidence.subset(keep)
    folds = leave_one_group_out(short, scores, classes, ObserveConfig())
    choice = choose_ra_variant(short, folds, "mixture", classes)
    assert choice.too_little_evidence and choice.variant == ROBUST_RA_VARIANT
    assert choice.objects_per_class["c"] < MIN_HELD_OUT_OBJECTS <= choice.objects_per_class["a"]
    assert "'c'" in choice.reason and "'a'" not in choice.reason
    recorded = choice.to_dict()
    assert recorded["too_little_evidence"] is True and recorded["robust_default"] == "class"


def test_the_mixture_never_weighs_a_reported_only_variant() -> None:
    """A region bad for every class is ra_region's best case; it is fitted and reported, but
    left out of the mixture's table (it is not selectable, docs/decisions/0006)."""
    from rapomdp.awareness.variants import REPORTED_ONLY

    rng = np.random.default_rng(3)
    directions = fibonacci_directions(64, hemisphere=True)
    bad = directions[:, 2] > 0.7
    classes = 4
    labels = np.repeat(np.arange(classes), 4)
    right = rng.random((labels.size, 64)) < np.where(bad, 0.1, 0.9)[None]
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % classes)
    evidence = Evidence(labels, predicted, np.tile(np.arange(4), classes))
    flat = np.full((classes, 64), 0.5)
    names = [str(c) for c in range(classes)]
    folds = leave_one_group_out(evidence, {"mean": flat, "area": flat}, names, ObserveConfig(),
                                directions)
    assert REPORTED_ONLY == {"region"} and all("ra_region" in m for _, m in folds)
    choice = choose_ra_variant(evidence, folds, "mixture", names)
    assert "region" not in choice.held_out
    assert choice.best == "viewpoint"  # the per-class region term finds it too
    weights, _ = ra_mixture_folds(evidence, folds, names)
    assert "ra_region" not in weights and "ra_viewpoint" in weights


def test_mixture_weights_recover_a_planted_mixture_and_refuse_zero_probabilities() -> None:
    rng = np.random.default_rng(0)
    first, second = np.array([0.7, 0.1, 0.1, 0.1]), np.array([0.1, 0.1, 0.1, 0.7])
    source = rng.random(20_000) < 0.3  # 30 % of the labels drawn from the first model
    labels = np.where(source, rng.choice(4, 20_000, p=first), rng.choice(4, 20_000, p=second))
    w = fit_mixture_weights(np.stack([first[labels], second[labels]]))
    assert w.sum() == pytest.approx(1.0) and w[0] == pytest.approx(0.3, abs=0.02)
    # a model that is the truth against a uniform one takes almost all the weight
    truth = fit_mixture_weights(np.stack([second[labels[~source]], np.full((~source).sum(), 0.25)]))
    assert truth[0] > 0.95
    with pytest.raises(ValueError, match="positive probabilities"):
        fit_mixture_weights(np.array([[0.5, 0.0], [0.5, 0.5]]))


def test_each_folds_mixture_is_weighted_without_the_group_it_scores() -> None:
    """Group 0's objects are always misread, groups 1 and 2 always read right: group 0's
    fold weighs the variants on groups 1-2 alone (all on the one that says 'right'), and the
    mixture over every group weighs both."""
    classes = ["a", "b"]
    labels = np.array([0, 1, 0, 1, 0, 1])
    groups = np.array([0, 0, 1, 1, 2, 2])
    predicted = np.where(groups[:, None] == 0, 1 - labels[:, None], labels[:, None])
    predicted = np.repeat(predicted, 4, axis=1)  # (6, 4 viewpoints)
    evidence = Evidence(labels, predicted, groups)

    def table(p_correct: float) -> ObservationModel:
        return ObservationModel(np.broadcast_to(np.array([[p_correct, 1 - p_correct],
                                                          [1 - p_correct, p_correct]]),
                                                (4, 2, 2)).copy(), classes)

    models = {"ra_right": table(0.9), "ra_wrong": table(0.1), "ra_region": table(0.5),
              "classifier": table(0.5)}
    folds = [(groups == g, dict(models)) for g in range(3)]
    weights, mixed = ra_mixture_folds(evidence, folds, classes)
    assert set(weights) == {"ra_right", "ra_wrong"}  # the RA variants but the reported-only
    assert 0.5 < weights["ra_right"] < 0.8  # a third of the labels are misread
    fold_weights = [m["ra_mixture"].calibration.weights for _, m in mixed]
    assert fold_weights[0]["ra_right"] > 0.99  # fitted on groups 1-2: always right
    assert 0.3 < fold_weights[1]["ra_right"] < 0.7  # groups 0 and 2: half misread
    assert np.allclose(mixed[0][1]["ra_mixture"].probabilities[:, 0, 0],
                       0.9 * fold_weights[0]["ra_right"] + 0.1 * fold_weights[0]["ra_wrong"])
    with pytest.raises(ValueError, match="two groups of held-out evidence"):
        ra_mixture_folds(evidence, folds[:1], classes)
