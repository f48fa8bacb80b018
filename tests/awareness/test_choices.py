"""The observe stage's held-out choices as one function: what it chooses on planted evidence,
how ``ra`` follows the chosen variant, and where it refuses."""

from __future__ import annotations

import numpy as np
import pytest

from rapomdp.awareness.choices import held_out_choices
from rapomdp.awareness.evidence import Evidence
from rapomdp.awareness.mixture import ROBUST_RA_VARIANT, choose_ra_variant
from rapomdp.awareness.variants import leave_one_group_out
from rapomdp.config import ObserveConfig
from rapomdp.geometry.viewsphere import fibonacci_directions
from rapomdp.workspace import StageError
from tests.awareness.test_evidence import _planted_area_evidence

CLASSES = ["a", "b", "c"]


def _planted_class_rates(rates: list[float], seed: int, groups: int = 4, spread: float = 1.5,
                         views: int = 64) -> tuple[Evidence, dict[str, np.ndarray]]:
    """Each object right on its views at its own rate: logit N(logit(its class's rate), spread)."""
    rng = np.random.default_rng(seed)
    c = len(rates)
    scores = {"mean": rng.random((c, views)), "area": rng.random((c, views))}
    labels, groups_of = np.repeat(np.arange(c), groups), np.tile(np.arange(groups), c)
    logit = np.log(np.array(rates) / (1 - np.array(rates)))[labels]
    own = 1.0 / (1.0 + np.exp(-(logit + spread * rng.standard_normal(labels.size))))
    right = rng.random((labels.size, views)) < own[:, None]
    predicted = np.where(right, labels[:, None], (labels[:, None] + 1) % c)
    return Evidence(labels, predicted, groups_of), scores


def test_a_variant_by_name_is_ra_and_ra_is_its_entry_everywhere() -> None:
    evidence, scores = _planted_area_evidence(4, 8)
    directions = fibonacci_directions(96, hemisphere=True)
    cfg = ObserveConfig(ra_model="class_area")
    chosen = held_out_choices(evidence, scores, CLASSES, cfg, directions, seed=3)
    alone = choose_ra_variant(evidence, leave_one_group_out(evidence, scores, CLASSES, cfg,
                                                            directions), "class_area", CLASSES)
    assert chosen.choice == alone and chosen.variant == "class_area"
    assert chosen.choice.rule == "configured"
    ra = f"ra_{chosen.variant}"
    assert chosen.single_view["ra"] is chosen.single_view[ra]
    for per_model in (chosen.shrinkage, chosen.corrections, chosen.temperatures,
                      chosen.declared):
        assert per_model["ra"] == per_model[ra]
    assert set(chosen.corrections.values()) == {"temperature"}  # every model tempered
    assert len(chosen.belief_folds) == 4 and len(chosen.validation) == len(chosen.single_view) - 1
    for model in chosen.single_view.values():
        assert np.allclose(model.probabilities.sum(axis=2), 1.0)
    assert chosen.kernel_grid == []  # no similarity scores: ra_transfer's default kernel


def test_errors_shared_within_an_object_temper_the_belief() -> None:
    """Each object right at its own rate: its views are not independent given the class, so
    the held-out walks make the belief count them less (t < 1)."""
    evidence, scores = _planted_class_rates([0.6, 0.7, 0.8], seed=2, groups=5, spread=2.5)
    directions = fibonacci_directions(64, hemisphere=True)
    chosen = held_out_choices(evidence, scores, CLASSES, ObserveConfig(), directions, seed=0)
    for name in ("classifier", "ra"):
        assert chosen.corrections[name] == "temperature"
        assert 0.0 < chosen.temperatures[name] < 0.9
        assert 0.0 <= chosen.declared[name].temperature <= 2.0


def test_one_group_chooses_nothing_and_a_stacked_variant_is_refused() -> None:
    evidence, scores = _planted_area_evidence(4, 9)
    one = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    directions = fibonacci_directions(96, hemisphere=True)
    chosen = held_out_choices(one, scores, CLASSES, ObserveConfig(), directions, seed=0)
    assert (chosen.variant, chosen.choice.rule) == (ROBUST_RA_VARIANT, "too little evidence")
    assert chosen.belief_folds == [] and chosen.declared == {}
    assert set(chosen.temperatures.values()) == {1.0}
    assert set(chosen.corrections.values()) == {"none"}
    with pytest.raises(StageError, match="'viewpoint' stacks over groups"):
        held_out_choices(one, scores, CLASSES, ObserveConfig(ra_model="viewpoint"),
                         directions, seed=0)


def test_empty_evidence_is_refused_by_name() -> None:
    evidence, scores = _planted_area_evidence(4, 9)
    with pytest.raises(ValueError, match="no held-out evidence"):
        held_out_choices(evidence.subset(evidence.groups > 9), scores, CLASSES,
                         ObserveConfig(), fibonacci_directions(96, hemisphere=True), seed=0)


def test_the_mixture_averages_the_variants_it_weighs_and_ra_is_it() -> None:
    evidence, scores = _planted_area_evidence(4, 8)
    directions = fibonacci_directions(96, hemisphere=True)
    chosen = held_out_choices(evidence, scores, CLASSES, ObserveConfig(ra_model="mixture"),
                              directions, seed=3)
    mixture = chosen.single_view["ra"]
    assert chosen.variant == "mixture" and mixture is chosen.single_view["ra_mixture"]
    weights = mixture.calibration.weights  # type: ignore[attr-defined]
    # the RA variants (no similarity scores planted: no ra_transfer), not the reported-only
    assert set(weights) == {"ra_paper", "ra_class", "ra_area", "ra_class_area", "ra_viewpoint"}
    assert sum(weights.values()) == pytest.approx(1.0)
    # the planted signal is the salient area: the area variants carry most of the weight
    assert weights["ra_area"] + weights["ra_class_area"] + weights["ra_viewpoint"] > 0.5
    table = sum(w * chosen.single_view[name].probabilities for name, w in weights.items())
    assert np.allclose(mixture.probabilities, table)
    for _, models in chosen.belief_folds:  # each fold its own mixture, weighted without it
        fold_weights = models["ra_mixture"].calibration.weights  # type: ignore[attr-defined]
        assert set(fold_weights) == set(weights)
        assert np.allclose(models["ra_mixture"].probabilities.sum(axis=2), 1.0)
    assert chosen.shrinkage["ra"].amount == 0.0
    # the held-out validation scores the mixture too, each group by weights fitted without it
    rows = {str(row["model"]): row for row in chosen.validation}
    assert [row["model"] for row in chosen.validation].count("ra_mixture") == 1
    variants = [float(rows[name]["log_likelihood"]) for name in weights]
    assert min(variants) < float(rows["ra_mixture"]["log_likelihood"])
    assert float(rows["ra_mixture"]["log_likelihood"]) > max(variants) - 0.02


def test_the_mixture_falls_back_on_one_group() -> None:
    evidence, scores = _planted_area_evidence(4, 9)
    directions = fibonacci_directions(96, hemisphere=True)
    one = Evidence(evidence.labels, evidence.predicted, np.zeros_like(evidence.groups))
    chosen = held_out_choices(one, scores, CLASSES, ObserveConfig(ra_model="mixture"),
                              directions, seed=0)
    assert (chosen.variant, chosen.choice.rule) == (ROBUST_RA_VARIANT, "too little evidence")
    assert "ra_mixture" not in chosen.single_view
    assert chosen.single_view["ra"] is chosen.single_view["ra_class"]
