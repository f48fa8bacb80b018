"""The wrong labels' shrinkage toward uniform, chosen on held-out objects."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.evidence import (
    Evidence,
)
from rapomdp.awareness.observation import (
    ObservationModel,
)
from rapomdp.awareness.shrinkage import (
    WRONG_LABEL_SHRINKAGES,
    choose_wrong_label_shrinkage,
    shrink_wrong_labels,
)
from rapomdp.awareness.variants import leave_one_group_out
from rapomdp.config import ObserveConfig


def test_shrinking_wrong_labels_keeps_p_correct_and_ends_at_uniform() -> None:
    rng = np.random.default_rng(3)
    p = rng.dirichlet(np.ones(4), size=(6, 4))  # (V, C, C)
    idx = np.arange(4)
    for amount in WRONG_LABEL_SHRINKAGES:
        shrunk = shrink_wrong_labels(p, amount)
        np.testing.assert_allclose(shrunk.sum(axis=2), 1.0)
        np.testing.assert_array_equal(shrunk[:, idx, idx], p[:, idx, idx])
    np.testing.assert_array_equal(shrink_wrong_labels(p, 0.0), p)
    uniform = shrink_wrong_labels(p, 1.0)
    wrong = ~np.eye(4, dtype=bool)
    np.testing.assert_allclose(uniform[:, wrong].reshape(6, 4, 3),
                               np.repeat(((1 - p[:, idx, idx]) / 3)[:, :, None], 3, axis=2))
    half = shrink_wrong_labels(p, 0.5)
    np.testing.assert_allclose(half, (p + uniform) / 2)
    with pytest.raises(ValueError, match=r"shrink a \(V, C, C\) model, got shape \(6, 4\)"):
        shrink_wrong_labels(p[:, 0], 0.5)
    with pytest.raises(ValueError, match=r"in \[0, 1\], got 1.5"):
        shrink_wrong_labels(p, 1.5)


def _planted_wrong_labels(per_object: bool, seed: int, groups: int = 4
                          ) -> tuple[Evidence, dict[str, np.ndarray]]:
    """Eight classes, ``groups`` held-out objects each, right on 60 % of the views; every wrong
    view of an object names one class: the object's own (``per_object``, drawn: where one
    object's mistakes go says little of another's) or its class's (the same for every object)."""
    rng = np.random.default_rng(seed)
    classes, views = 8, 48
    labels = np.repeat(np.arange(classes), groups)
    right = rng.random((labels.size, views)) < 0.6
    offset = rng.integers(1, classes, labels.size) if per_object else np.ones(labels.size, int)
    predicted = np.where(right, labels[:, None], ((labels + offset) % classes)[:, None])
    scores = {"mean": rng.random((classes, views)), "area": rng.random((classes, views))}
    return Evidence(labels, predicted, np.tile(np.arange(groups), classes)), scores


def test_the_wrong_label_shrinkage_is_chosen_where_mistakes_do_not_transfer() -> None:
    names = list("abcdefgh")
    evidence, scores = _planted_wrong_labels(per_object=True, seed=4)
    folds = leave_one_group_out(evidence, scores, names, ObserveConfig())
    for model in ("blackbox", "ra_class", "classifier"):
        choice = choose_wrong_label_shrinkage(evidence, folds, model)
        assert choice.rule == "best" and choice.amount >= 0.75, (model, choice)
        row = choice.held_out[f"{choice.amount:g}"]
        assert row["difference_to_none"] > row["standard_error"] > 0
        assert row["mean_log_likelihood"] == max(r["mean_log_likelihood"]
                                                 for r in choice.held_out.values())
        assert choice.held_out["0"]["difference_to_none"] == 0.0
        assert "more than one standard error" in choice.reason
    # mistakes every object of a class makes alike: the counted wrong labels are kept
    evidence, scores = _planted_wrong_labels(per_object=False, seed=4)
    folds = leave_one_group_out(evidence, scores, names, ObserveConfig())
    choice = choose_wrong_label_shrinkage(evidence, folds, "blackbox")
    assert (choice.amount, choice.rule) == (0.0, "best")
    assert all(r["difference_to_none"] < 0 for a, r in choice.held_out.items() if a != "0")
    assert choice.to_dict()["grid"] == list(WRONG_LABEL_SHRINKAGES)


def test_the_wrong_label_shrinkage_needs_held_out_objects() -> None:
    names = list("abcdefgh")
    evidence, scores = _planted_wrong_labels(per_object=True, seed=5)
    one = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    none_held = leave_one_group_out(one, scores, names, ObserveConfig())
    choice = choose_wrong_label_shrinkage(one, none_held, "blackbox")
    assert (choice.amount, choice.rule, choice.held_out) == (0.0, "too little evidence", {})
    assert choice.reason.startswith("too little held-out evidence to choose")


def test_a_gain_within_one_standard_error_keeps_the_counted_wrong_labels() -> None:
    """Four held-out objects make their mistakes where the counted rows expect them, two
    elsewhere: uniform wrong labels gain on average, by less than one standard error."""

    rows = np.array([[0.5, 0.45, 0.05], [0.05, 0.5, 0.45], [0.45, 0.05, 0.5]])
    model = ObservationModel(rows[None], ["a", "b", "c"])  # one viewpoint
    labels = np.array([0, 0, 1, 1, 2, 2])
    expected = (labels + 1) % 3  # where the rows put a class's mistakes
    elsewhere = np.array([True, False, True, False, False, False])
    wrong = np.where(elsewhere, (labels + 2) % 3, expected)
    predicted = np.where(np.arange(10)[None] < 5, labels[:, None], wrong[:, None])
    evidence = Evidence(labels, predicted, np.array([0, 1, 0, 1, 0, 1]))
    folds = [(evidence.groups == g, {"m": model}) for g in (0, 1)]
    choice = choose_wrong_label_shrinkage(evidence, folds, "m")
    assert (choice.amount, choice.rule) == (0.0, "one standard error")
    best = max(choice.held_out.values(), key=lambda r: r["mean_log_likelihood"])
    assert 0 < best["difference_to_none"] <= best["standard_error"]
    uniform = choice.held_out["1"]  # per object: 5 wrong views of 10, log(0.25 / row's share)
    d = np.where(elsewhere, 0.5 * np.log(0.25 / 0.05), 0.5 * np.log(0.25 / 0.45))
    assert uniform["difference_to_none"] == pytest.approx(d.mean())
    assert uniform["standard_error"] == pytest.approx(d.std(ddof=1) / np.sqrt(6))
    assert "not better than none by more than one standard error" in choice.reason


def test_a_model_some_folds_cannot_fit_is_chosen_on_the_folds_that_have_it() -> None:
    """ra_viewpoint stacks over groups: a fold left with one group has none; the choice reads
    the folds that fitted it, and no fold at all is too little evidence."""
    names = list("abcdefgh")
    evidence, scores = _planted_wrong_labels(per_object=True, seed=4)
    folds = leave_one_group_out(evidence, scores, names, ObserveConfig())
    full = choose_wrong_label_shrinkage(evidence, folds, "blackbox")
    missing = [(held, {k: m for k, m in models.items() if k != "blackbox"}) if i == 0
               else (held, models) for i, (held, models) in enumerate(folds)]
    fewer = choose_wrong_label_shrinkage(evidence, missing, "blackbox")
    assert fewer.rule == "best" and fewer.amount >= 0.75
    assert fewer.held_out["1"] != full.held_out["1"]  # one group fewer scored
    none = [(held, {k: m for k, m in models.items() if k != "blackbox"})
            for held, models in folds]
    assert choose_wrong_label_shrinkage(evidence, none, "blackbox").rule == \
        "too little evidence"


def test_shrunk_folds_shrink_the_named_models_wrong_labels_and_keep_the_rest():
    from rapomdp.awareness.shrinkage import shrunk_folds

    rng = np.random.default_rng(3)
    p = rng.dirichlet(np.ones(3), size=(4, 3))
    held = np.array([True, False])
    folds = [(held, {"a": ObservationModel(p, ["x", "y", "z"]),
                     "b": ObservationModel(p, ["x", "y", "z"])})]
    (mask, models), = shrunk_folds(folds, {"a": 0.5})
    assert mask is held
    assert np.allclose(models["a"].probabilities, shrink_wrong_labels(p, 0.5))
    assert models["b"] is folds[0][1]["b"]
    idx = np.arange(3)
    assert np.allclose(models["a"].probabilities[:, idx, idx], p[:, idx, idx])


